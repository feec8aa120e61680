"""The service killed with SIGKILL: versions written until then survive intact, running jobs are marked
failed (interrupted) at the next start, and the orphaned calibration worker and its pool processes exit by
themselves. Stopped, it stops its calibration's processes too.

The service killed or stopped is a real ``rigd serve``; what the next start finds is read through rigd's app
built on the same data directory in this process (:class:`App`: the start's own code, without a second
interpreter's imports)."""

from __future__ import annotations

import sqlite3
import threading
import time

import httpx
import numpy as np
from api_helpers import (
    POOL,
    App,
    Server,
    descendants,
    gone,
    matrix,
    perturbed_truth,
    simulated_dataset,
    wait_running,
    worker_pid,
)
from scipy.spatial.transform import Rotation


def random_transform(rng: np.random.Generator) -> dict[str, list[float]]:
    return {"rpy_deg": rng.uniform(-170, 170, 3).tolist(), "xyz_m": rng.uniform(-1, 1, 3).tolist()}


def writer(url: str, seed: int, acked: dict[int, np.ndarray], activated: list[int], stop: threading.Event) -> None:
    """Store versions (activating every third) until the server dies; record what it acknowledged."""
    rng = np.random.default_rng(seed)
    with httpx.Client(base_url=url, timeout=10.0) as client:
        try:
            while not stop.is_set():
                response = client.post("/extrinsics/versions", json={
                    "T_camera_lidar": random_transform(rng), "note": f"writer {seed}", "activate": rng.random() < 0.3})
                assert response.status_code == 201, response.text
                version = response.json()
                acked[version["number"]] = matrix(version["T_camera_lidar"])
                if version["status"] == "active":
                    activated.append(version["number"])
        except httpx.TransportError:
            return  # the server is gone


def test_sigkill_while_writing_versions_keeps_the_history_intact(tmp_path):
    server = Server(tmp_path / "data").start()
    acked: dict[int, np.ndarray] = {}
    activated: list[int] = []
    stop = threading.Event()
    threads = [threading.Thread(target=writer, args=(server.url, s, acked, activated, stop)) for s in (1, 2)]
    for t in threads:
        t.start()
    while len(acked) < 40:  # two writers keep a version write in flight almost all the time
        time.sleep(0.01)
    server.kill()
    stop.set()
    for t in threads:
        t.join(timeout=30)

    db = tmp_path / "data" / "rigd.db"
    with sqlite3.connect(db) as conn:  # the file is consistent as SQLite sees it
        assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    restarted = App(tmp_path / "data").start()
    with restarted.client() as client:
        versions = client.get("/extrinsics/versions").json()
    restarted.stop()
    numbers = [v["number"] for v in versions]
    assert numbers == list(range(1, len(numbers) + 1))  # no gap, nothing half-written
    assert set(acked) <= set(numbers)  # every acknowledged version survived ...
    for v in versions:
        if v["number"] in acked:  # ... unchanged
            assert np.array_equal(matrix(v["T_camera_lidar"]), acked[v["number"]])
        T = v["T_camera_lidar"]  # and each one's four forms agree (the row was written whole)
        R = matrix(T)[:3, :3]
        assert np.allclose(Rotation.from_quat(T["quaternion_xyzw"]).as_matrix(), R, atol=1e-9)
        assert np.allclose(Rotation.from_euler("ZYX", T["rpy_deg"][::-1], degrees=True).as_matrix(), R, atol=1e-9)
        assert np.allclose(T["xyz_m"], matrix(T)[:3, 3])
        if v["number"] == 1:
            assert v["supersedes"] is None
        else:  # the version that was active when it was stored
            assert 1 <= v["supersedes"] < v["number"]
    active = [v["number"] for v in versions if v["status"] == "active"]
    assert len(active) == 1
    # The active one is the last acknowledged activation or a later one committed just before the kill.
    assert active[0] >= max(activated, default=1)


def test_sigkill_during_a_calibration_marks_it_interrupted_and_leaves_no_process(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=3)
    server = Server(data, env=POOL).start()
    assert server.proc is not None
    with server.client() as client:
        job = client.post("/calibrate", json={"dataset": "ds", "init": perturbed_truth(dataset)}).json()
        pid = worker_pid(wait_running(client, job["id"])["log_tail"])
        wait_running(client, job["id"], "edges of")  # the worker's pool processes have started
        started = descendants(server.proc.pid)
    assert pid in started and len(started) >= 3, started  # the worker, two pool processes (and their tracker)
    server.kill()
    killed = time.monotonic()
    # The worker's stdin closed with the server: it ends its process group instead of finishing.
    while alive := [p for p in started if not gone(p)]:
        assert time.monotonic() < killed + 10, f"processes {alive} of the killed service still run"
        time.sleep(0.1)
    print(f"no process of the killed service after {time.monotonic() - killed:.2f} s")

    restarted = App(data).start()
    with restarted.client() as client:
        after = client.get(f"/jobs/{job['id']}").json()
        assert after["status"] == "failed" and "interrupted" in after["error"]
        assert after["finished_at"] is not None
        assert client.get("/extrinsics/versions").json() == []  # nothing half-stored
        assert client.get("/status").json()["running_jobs"] == []
    restarted.stop()


def test_stopping_the_service_fails_a_running_calibration_cleanly(tmp_path):
    data = tmp_path / "data"
    dataset = simulated_dataset(data, "ds", pairs=3)
    server = Server(data, env=POOL).start()
    assert server.proc is not None
    with server.client() as client:
        job = client.post("/calibrate", json={"dataset": "ds", "init": perturbed_truth(dataset)}).json()
        wait_running(client, job["id"], "edges of")
        started = descendants(server.proc.pid)
    asked = time.monotonic()
    server.stop()
    took = time.monotonic() - asked
    print(f"rigd serve stopped in {took:.2f} s")
    assert took < 10, f"stopping took {took:.1f} s"
    assert [p for p in started if not gone(p)] == []  # its calibration's processes went with it
    restarted = App(data).start()
    with restarted.client() as client:
        after = client.get(f"/jobs/{job['id']}").json()
    restarted.stop()
    assert after["status"] in {"failed", "succeeded"}  # it may finish in the shutdown window
    if after["status"] == "failed":
        assert after["error"] == "interrupted: the service stopped"
