"""``rigd evaluate ... --cluster``: a real Dask scheduler and two worker processes on loopback, started here;
the trials' results equal the local pool's, and each worker extracts the features once."""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from distributed import Client

import rigd
from rigd.cli import main
from rigd.cli.exit_codes import ERROR
from rigd.dataset import write_pair
from rigd.dataset.pcd import Cloud
from rigd.evaluate.cluster import dataset_stamp, worker_counts

REPO = Path(rigd.__file__).resolve().parents[1]
TRIALS = 3  # more trials than workers: some worker runs two, and must not extract twice


def _wait_for(path: Path, proc: subprocess.Popen, log: Path) -> None:
    deadline = time.monotonic() + 60
    while not path.exists():
        if proc.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"dask scheduler did not start: {log.read_text()}")
        time.sleep(0.1)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """(address, client) of a scheduler and 2 single-threaded worker processes on 127.0.0.1, running this
    tree's rigd (PYTHONPATH) as an installed rigd would be on each machine."""
    tmp = tmp_path_factory.mktemp("dask")
    path = [str(REPO), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(path)}
    info = tmp / "scheduler.json"
    procs = []

    def start(module: str, *args: str) -> subprocess.Popen:
        log = tmp / f"{module.rsplit('_', 1)[-1]}.log"
        proc = subprocess.Popen([sys.executable, "-m", f"distributed.cli.{module}", *args], env=env, cwd=tmp,
                                stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True)
        procs.append(proc)
        return proc

    try:
        scheduler = start("dask_scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                          "--scheduler-file", str(info))
        _wait_for(info, scheduler, tmp / "scheduler.log")
        address = json.loads(info.read_text())["address"]
        start("dask_worker", address, "--nworkers", "2", "--nthreads", "1", "--host", "127.0.0.1",
              "--no-dashboard")
        with Client(address, timeout=30, set_as_default=False) as client:
            client.wait_for_workers(2, timeout=60)
            yield address, client
    finally:
        for proc in reversed(procs):  # the worker first, then its scheduler; each with its children
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


def _convergence(dataset, out, capsys, *where):
    code = main(["evaluate", "convergence", str(dataset), "--trials", str(TRIALS), "--seed", "4", "--out", str(out),
                 "--no-uncertainty", "--sigmas-deg", "3.5,1.8", *where])  # two levels: the same code, quicker trials
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return yaml.safe_load((out / "convergence.yaml").read_text()), captured.out


def _without_times(run: dict) -> dict:
    return {k: v for k, v in run.items() if k != "wall_time_s"}


def test_cluster_runs_equal_the_local_pool_and_extract_once_per_worker(small_dataset, cluster, tmp_path, capsys):
    address, client = cluster
    before = client.run(worker_counts)
    # One local worker (the trials' numbers do not depend on how many: test_protocols.py): one extraction less
    local, _ = _convergence(small_dataset, tmp_path / "local", capsys, "--workers", "1")
    remote, printed = _convergence(small_dataset, tmp_path / "cluster", capsys, "--cluster", address)
    after = client.run(worker_counts)

    assert f"workers: 2 of the cluster at {address}" in printed
    assert remote["settings"]["cluster"] == address and local["settings"]["cluster"] is None
    assert [r["index"] for r in remote["runs"]] == list(range(TRIALS))
    assert all(r["result"] is not None for r in remote["runs"])
    # Same code, same features, same starts: every number of every run is the same, to the last bit.
    assert [_without_times(r) for r in remote["runs"]] == [_without_times(r) for r in local["runs"]]
    for key in ("converged", "solution", "std", "error_vs_ground_truth"):
        assert remote["summary"][key] == local["summary"][key], key
    # Features once per worker process: every trial ran on a worker, none extracted twice for this dataset.
    tasks = {w: after[w].get("tasks", 0) - before.get(w, {}).get("tasks", 0) for w in after}
    extractions = {w: after[w].get("extractions", 0) - before.get(w, {}).get("extractions", 0) for w in after}
    assert sum(tasks.values()) == TRIALS
    assert extractions == {w: int(n > 0) for w, n in tasks.items()}, (tasks, extractions)


def test_worker_errors_name_the_worker(small_dataset, cluster, tmp_path, capsys):
    address, _ = cluster
    root = tmp_path / "blank"
    (root / "pairs").mkdir(parents=True)
    for name in ("rig.yaml", "ground_truth.yaml"):
        (root / name).write_text((small_dataset / name).read_text())
    pts = np.random.default_rng(0).normal(size=(500, 3)) + [5.0, 0.0, 0.0]
    write_pair(root, 0, np.full((256, 512), 128, np.uint8), Cloud(pts), {})
    assert main(["evaluate", "convergence", str(root), "--trials", "2", "--cluster", address]) == ERROR
    err = capsys.readouterr().err
    assert "featureless" in err and "on worker tcp://127.0.0.1:" in err


def test_unreachable_or_malformed_address_is_a_clear_error(small_dataset, capsys):
    with socket.socket() as s:  # a loopback port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    assert main(["evaluate", "convergence", str(small_dataset), "--trials", "1", "--cluster", address,
                 "--cluster-timeout", "1"]) == ERROR
    err = capsys.readouterr().err
    assert address in err and "no Dask scheduler" in err
    assert main(["evaluate", "precision", str(small_dataset), "--size", "1", "--cluster", "tcp://127.0.0.1"]) == ERROR
    assert "not a scheduler address" in capsys.readouterr().err


def test_a_rewritten_dataset_has_a_new_stamp(small_dataset, tmp_path):
    """Workers keep features per (path, stamp, settings): a dataset rewritten at the same path is re-extracted."""
    root = tmp_path / "copy"
    shutil.copytree(small_dataset, root)  # copy2: same sizes and times
    stamp = dataset_stamp(root)
    assert stamp == dataset_stamp(small_dataset)
    (root / "evaluation").mkdir()  # the default output directory is not part of the dataset
    (root / "evaluation" / "convergence.yaml").write_text("x")
    assert dataset_stamp(root) == stamp
    cloud = next((root / "pairs").rglob("*.pcd"))
    os.utime(cloud, ns=(cloud.stat().st_atime_ns, cloud.stat().st_mtime_ns + 1))
    assert dataset_stamp(root) != stamp
