"""A hostile probe of rigd: bad files, kill -9 at chosen moments, a full disk, crafted names. Prints a table of
every attempt, what was expected, what happened, and a verdict (ok, FAILED, or not run and why).

Run: .venv/bin/python benchmarks/probe.py [--rounds 4] [--only CLI|SERVICE|DISK]
Datasets are simulated (6 pairs at 256 x 128). The full-disk attempts mount a 12 MB tmpfs and so need root;
without it they are reported as not run (tests/rigd/api/test_full_disk.py covers the same with fault injection).
Each CLI attempt runs ``python -m rigd`` as a process, so its exit code and stderr are the user's.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import shutil
import signal
import sqlite3
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np
import yaml

from rigd.dataset import Cloud, open_dataset, write_pcd
from rigd.simulate import write_simulated_dataset
from rigd.store.datasets import content_hash

REPO = Path(__file__).resolve().parents[1]
SMALL_PCAP = REPO / "tests/data/vlp16/vlp16_strongest_600rpm_84pkts.pcap"
LEGACY_PCAP = REPO / "tests/data/vlp16/vlp16_legacyfw_1200rpm_50rot.pcap"


@dataclass(frozen=True)
class Row:
    finding: str  # the finding's number in the probe's list
    attempt: str
    expected: str
    got: str
    ok: bool | None  # None: not run


class Probe:
    """A scratch folder with a simulated dataset, and ``rigd`` as a process."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.dataset = write_simulated_dataset(root / "D", "indoor", 6, 5, width=256, height=128, progress=False)

    def copy(self, name: str) -> Path:
        target = self.root / name
        shutil.copytree(self.dataset, target)
        return target

    def rigd(self, *args: str, timeout: float = 300) -> tuple[int, str]:
        """Exit code and stderr of ``python -m rigd ARGS``."""
        proc = self.run(*args, timeout=timeout)
        return proc.returncode, proc.stderr

    def run(self, *args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "rigd", *args], capture_output=True, text=True, timeout=timeout,
                              cwd=self.root)

    def guess(self) -> str:
        truth = open_dataset(self.dataset).ground_truth
        assert truth is not None
        return ",".join(f"{v:.4f}" for v in (*(truth.rpy_deg + 1.0), *(truth.translation_m + 0.02)))


def error_line(err: str) -> str:
    """The ``rigd: error: ...`` line of stderr (progress lines come before it), else a traceback's last line."""
    lines = [line for line in err.strip().splitlines() if line.strip()]
    return next((line for line in reversed(lines) if line.startswith("rigd: ")), lines[-1] if lines else "")


def said(code: int, err: str) -> str:
    """An exit code and its message."""
    line = error_line(err)
    return f"exit {code}" + (" (traceback)" if "Traceback" in err else "") + (f": {line[:110]}" if line else "")


def named(code: int, err: str, wanted: int) -> bool:
    """Exit ``wanted`` with one ``rigd: error:`` line, no traceback."""
    return code == wanted and "Traceback" not in err and error_line(err).startswith("rigd: error: ")


# -- the command line -----------------------------------------------------------------------------------------------
def export_over_its_input(p: Probe) -> Row:
    folder = p.root / "X"
    folder.mkdir()
    record = folder / "extrinsics.yaml"
    record.write_text(yaml.safe_dump({"T_camera_lidar": {"rpy_deg": [0, 10, -50], "xyz_m": [0.1, 0, -0.1]}}))
    before = record.read_bytes()
    code, err = p.rigd("export", str(record), "--format", "kalibr", "--out", str(record))
    return Row("2", "export X/extrinsics.yaml --format kalibr --out X/extrinsics.yaml", "exit 73, record kept",
               said(code, err), named(code, err, 73) and record.read_bytes() == before)


def calibrate_twice_into_one_out(p: Probe) -> Row:
    out = p.root / "O"
    fewer = p.copy("D4")
    for pair in sorted((fewer / "pairs").iterdir())[4:]:
        shutil.rmtree(pair)
    first = p.rigd("calibrate", str(p.dataset), "--init", p.guess(), "--out", str(out), "--workers", "1")
    before = sorted(str(f.relative_to(out)) for f in out.rglob("*")) if out.is_dir() else []
    code, err = p.rigd("calibrate", str(fewer), "--init", p.guess(), "--out", str(out), "--workers", "1")
    after = sorted(str(f.relative_to(out)) for f in out.rglob("*")) if out.is_dir() else []
    got = f"first exit {first[0]}, second {said(code, err)}; the first run's {len(before)} files " + \
        ("kept as they were" if after == before else "mixed with others")
    return Row("3", "calibrate D --out O, then calibrate D4 (4 pairs) --out O", "second refused (73), nothing mixed",
               got, code == 73 and after == before and bool(before))


def lidar_export_over_another(p: Probe) -> Row:
    out = p.root / "sweeps"
    first = p.rigd("lidar", "export", str(SMALL_PCAP), "--out", str(out))
    before = sorted(f.name for f in out.iterdir()) if out.is_dir() else []
    code, err = p.rigd("lidar", "export", "--any-product", str(LEGACY_PCAP), "--out", str(out))
    after = sorted(f.name for f in out.iterdir()) if out.is_dir() else []
    return Row("4", "lidar export B.pcap --out D, where A.pcap's sweeps are", "exit 73, A's sweeps kept",
               f"first exit {first[0]}; {said(code, err)}", named(code, err, 73) and after == before)


def head_hash_covers_images(p: Probe) -> Row:
    head = write_simulated_dataset(p.root / "H", "indoor", 1, 5, width=256, height=128, progress=False, head=True)
    before = content_hash(open_dataset(head))
    image = sorted((head / "pairs" / "0000" / "images").iterdir())[0]
    pixels = cv2.imread(str(image))
    assert pixels is not None
    cv2.imwrite(str(image), 255 - pixels)
    after = content_hash(open_dataset(head))
    return Row("5", f"head dataset: change pairs/0000/images/{image.name}", "dataset_hash changes",
               "changed" if after != before else "the same", after != before)


INJECTION = 'x"""\nimport os;os.system("touch INJECTED")\n"""'


def launch_file_injection(p: Probe) -> list[Row]:
    folder = p.root / "E"
    folder.mkdir()
    (folder / "extrinsics.yaml").write_text(yaml.safe_dump({"T_camera_lidar": {"rpy_deg": [0, 0, 0],
                                                                                "xyz_m": [0, 0, 0]}}))
    code, err = p.rigd("export", str(folder), "--format", "ros2-launch", "--parent-frame", INJECTION,
                       "--out", str(p.root / "l.py"))
    rows = [Row("6", "export --format ros2-launch --parent-frame 'x\"\"\"\\nimport os;os.system(...)'",
                "exit 65, no file", said(code, err), named(code, err, 65) and not (p.root / "l.py").exists())]
    (folder / "bag.yaml").write_text(yaml.safe_dump({"frames": {"camera": INJECTION, "lidar": "velodyne"}}))
    code, err = p.rigd("export", str(folder), "--format", "urdf")
    rows.append(Row("6", "bag.yaml frames.camera holding code, export --format urdf", "exit 65",
                    said(code, err), named(code, err, 65)))
    return rows


def bad_copy(p: Probe, name: str, spoil: Callable[[Path], Any]) -> Path:
    """A copy of the dataset with ``spoil(copy)`` done to it."""
    copy = p.copy(name)
    spoil(copy)
    return copy


def big_png(path: Path) -> None:
    """A PNG whose header claims 60000 x 30000 pixels."""
    png = bytearray(cv2.imencode(".png", np.zeros((2, 2), np.uint8))[1].tobytes())
    png[16:24] = struct.pack(">II", 60000, 30000)
    png[29:33] = struct.pack(">I", zlib.crc32(bytes(png[12:29])))
    path.write_bytes(bytes(png))


def set_width(copy: Path, value: Any) -> None:
    rig = yaml.safe_load((copy / "rig.yaml").read_text())
    rig["camera"]["width"] = value
    (copy / "rig.yaml").write_text(yaml.safe_dump(rig))


HEADER_4E9 = (b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 4000000000\nHEIGHT 1\n"
              b"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4000000000\nDATA binary\n") + bytes(1200)
SPOILS: list[tuple[str, str, Callable[[Path], Any]]] = [
    ("11", "a cloud with 0 points", lambda d: write_pcd(d / "pairs/0000/cloud.pcd", Cloud(np.zeros((0, 3))))),
    ("11", "a cloud all NaN", lambda d: write_pcd(d / "pairs/0000/cloud.pcd", Cloud(np.full((99, 3), np.nan)))),
    ("11", "a PCD header claiming 4e9 points", lambda d: (d / "pairs/0000/cloud.pcd").write_bytes(HEADER_4E9)),
    ("11", "a PNG header claiming 60000x30000", lambda d: big_png(d / "pairs/0000/image.png")),
    ("11", "a pair folder named '²'", lambda d: (d / "pairs/0000").rename(d / "pairs/²")),
    ("13", "pair folders 0001 and 1", lambda d: shutil.copytree(d / "pairs/0001", d / "pairs/1")),
    ("13", "a point at 1e30 m", lambda d: write_pcd(d / "pairs/0000/cloud.pcd",
                                                     Cloud(np.array([[1e30, 0, 0], [1, 2, 3]])))),
    ("13", "ring -1", lambda d: write_pcd(d / "pairs/0000/cloud.pcd",
                                          Cloud(np.ones((3, 3)), ring=np.array([0, 1, -1], np.int16)))),
    ("13", "rig.yaml width: true", lambda d: set_width(d, True)),
    ("14", "a zero-byte PCD", lambda d: (d / "pairs/0000/cloud.pcd").write_bytes(b"")),
]


def bad_datasets(p: Probe) -> list[Row]:
    rows = []
    for k, (finding, what, spoil) in enumerate(SPOILS):
        copy = bad_copy(p, f"bad{k}", spoil)
        code, err = p.rigd("calibrate", str(copy), "--init", p.guess(), "--no-visuals", "--workers", "1",
                           "--out", str(p.root / f"bad{k}-out"))
        rows.append(Row(finding, f"calibrate: {what}", "exit 65, one line naming the file", said(code, err),
                        named(code, err, 65) and str(copy) in error_line(err)))
    return rows


def check_error_is_not_drift(p: Probe) -> list[Row]:
    nan = bad_copy(p, "nan", SPOILS[1][2])
    good = p.root / "good.yaml"
    good.write_text(yaml.safe_dump({"T_camera_lidar": {"rpy_deg": [0, 10, -50], "xyz_m": [0.1, 0, -0.1]}}))
    code, err = p.rigd("check", str(nan), "--against", str(good))
    rows = [Row("10", "rigd check on a dataset it cannot read", "exit 65, never 1 (drifted) or 2 (unknown)",
                said(code, err), named(code, err, 65))]
    empty = p.root / "empty.yaml"
    empty.write_text("")
    code, err = p.rigd("check", str(p.dataset), "--against", str(empty))
    rows.append(Row("14", "rigd check --against an empty extrinsics file", "exit 65 saying what it needs",
                    said(code, err), named(code, err, 65) and "needs matrix" in err))
    return rows


def damaged_database(p: Probe) -> list[Row]:
    data = p.root / "damaged"
    data.mkdir()
    (data / "rigd.db").write_bytes(b"SQLite format 3\x00" + bytes(84))
    rows = []
    for what, args in (("serve", ("serve", "--data-dir", str(data), "--port", "0")),
                       ("export", ("export", "1", "--format", "urdf", "--data-dir", str(data)))):
        code, err = p.rigd(*args, timeout=60)
        rows.append(Row("11", f"rigd {what} on a truncated rigd.db", "exit 65 naming the file", said(code, err),
                        named(code, err, 65) and "rigd.db" in err))
    return rows


def thinning(p: Probe) -> list[Row]:
    started = time.monotonic()
    code, err = p.rigd("dataset", "thin", str(p.dataset), str(p.root / "T"), "--azimuth-step-deg", "1e-14",
                       timeout=120)
    rows = [Row("12", "dataset thin --azimuth-step-deg 1e-14", "exit 65 at once",
                f"{said(code, err)} after {time.monotonic() - started:.1f} s", named(code, err, 65))]
    before = sorted(d.name for d in (p.dataset / "pairs").iterdir())
    code, err = p.rigd("dataset", "thin", str(p.dataset), str(p.dataset / "pairs" / "9999"))
    after = sorted(d.name for d in (p.dataset / "pairs").iterdir())
    rows.append(Row("13", "dataset thin D D/pairs/9999", "exit 73, D unchanged", said(code, err),
                    named(code, err, 73) and after == before))
    return rows


def corrupt_pcap(p: Probe) -> Row:
    data = bytearray(SMALL_PCAP.read_bytes())
    second = 24 + 16 + struct.unpack_from("<I", data, 24 + 8)[0]
    struct.pack_into("<I", data, second + 8, 0xFFFFFFF0)
    path = p.root / "corrupt.pcap"
    path.write_bytes(bytes(data))
    out = p.run("lidar", "info", str(path)).stdout
    bad = next((line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("bad packets")), "?")
    return Row("13", "lidar info: record 1's incl_len 0xFFFFFFF0 (83 packets behind it)",
               "a bad packet counted and what was not read named", f"bad packets: {bad}; "
               + ("names the unread bytes" if "claims 4294967280 bytes" in out else "says nothing of them"),
               bad != "0" and "claims 4294967280 bytes" in out)


# -- the service --------------------------------------------------------------------------------------------------
class Served:
    """``rigd serve`` on a free loopback port over ``data``."""

    def __init__(self, data: Path, env: dict[str, str] | None = None) -> None:
        with contextlib.closing(__import__("socket").socket()) as sock:
            sock.bind(("127.0.0.1", 0))
            self.port = sock.getsockname()[1]
        self.data = data
        environment = {k: v for k, v in os.environ.items() if not k.startswith("RIGD_")}
        environment.update({"RIGD_DATA_DIR": str(data), "RIGD_WORKERS": "1", **(env or {})})
        self.proc = subprocess.Popen([sys.executable, "-m", "rigd", "serve", "--port", str(self.port),
                                      "--log-level", "warning"], env=environment, stderr=subprocess.DEVNULL)
        self.client = httpx.Client(base_url=f"http://127.0.0.1:{self.port}", timeout=30)
        deadline = time.monotonic() + 60
        while True:
            with contextlib.suppress(httpx.TransportError):
                if self.client.get("/status").status_code == 200:
                    return
            if time.monotonic() > deadline or self.proc.poll() is not None:
                raise RuntimeError("rigd serve did not start")
            time.sleep(0.1)

    def job(self, job_id: int) -> dict[str, Any]:
        return dict(self.client.get(f"/jobs/{job_id}").json())

    def wait(self, job_id: int, until: Callable[[dict[str, Any]], bool], timeout: float = 300) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while not until(job := self.job(job_id)) and time.monotonic() < deadline:
            time.sleep(0.1)
        return job

    def end(self, how: signal.Signals = signal.SIGTERM) -> None:
        self.client.close()
        self.proc.send_signal(how)
        self.proc.wait(60)


def finished(job: dict[str, Any]) -> bool:
    return job["status"] in ("succeeded", "failed", "cancelled")


def service_data(p: Probe, where: Path) -> Path:
    shutil.copytree(p.dataset, where / "datasets" / "ds")
    return where


def calibrate_body(p: Probe) -> dict[str, Any]:
    values = [float(v) for v in p.guess().split(",")]
    return {"dataset": "ds", "init": {"rpy_deg": values[:3], "xyz_m": values[3:]}}


def version_of_job(db: Path, job_id: int, timeout: float = 600) -> int | None:
    """The number of the version job ``job_id`` stores, polled every 2 ms from the database as it commits."""
    deadline = time.monotonic() + timeout
    with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5)) as conn:
        while time.monotonic() < deadline:
            row = conn.execute("SELECT number FROM versions WHERE job_id = ?", (job_id,)).fetchone()
            if row is not None:
                return int(row[0])
            time.sleep(0.002)
    return None


def kill_between_version_and_job(p: Probe, rounds: int) -> Row:
    data = service_data(p, p.root / "svc-kill")
    kept = 0
    for _ in range(rounds):
        served = Served(data)
        job_id = served.client.post("/calibrate", json=calibrate_body(p)).json()["id"]
        number = version_of_job(data / "rigd.db", job_id)
        served.end(signal.SIGKILL)  # at once: between the version's commit and anything after it
        again = Served(data)
        job = again.job(job_id)
        kept += job["status"] == "succeeded" and (job["result"] or {}).get("version") == number
        again.end()
    return Row("1", f"kill -9 as soon as the job's version is in the store ({rounds} rounds)",
               "the job succeeded with that version after a restart", f"{kept} of {rounds}", kept == rounds)


def capture_while_calibrating(p: Probe) -> Row:
    served = Served(service_data(p, p.root / "svc-capture"))
    try:
        job_id = served.client.post("/calibrate", json=calibrate_body(p)).json()["id"]
        served.wait(job_id, lambda j: j["status"] != "queued", 60)
        answer = served.client.post("/capture", json={"dataset": "ds", "source": "sim", "n": 7})
        served.client.delete(f"/jobs/{job_id}")
        return Row("13", "POST /capture into a dataset while it calibrates", "409",
                   f"{answer.status_code}: {answer.json()['detail'][:90]}", answer.status_code == 409)
    finally:
        served.end()


def cheap_refusals(p: Probe) -> list[Row]:
    served = Served(service_data(p, p.root / "svc-cheap"))
    try:
        big = served.client.post("/calibrate", content=b"{" + b" " * 10_000_000 + b"}",
                                 headers={"Content-Type": "application/json"})
        traversal = served.client.get("/datasets/..%2F..%2Fetc")
        bad_frame = served.client.post("/extrinsics/versions", json={"T_camera_lidar": {
            "rpy_deg": [0, 0, 0], "xyz_m": [0, 0, 0]}})
        export = served.client.get("/extrinsics", params={"format": "urdf", "camera_frame": 'a"><x'})
    finally:
        served.end()
    return [Row("-", "a 10 MB body", "413", str(big.status_code), big.status_code == 413),
            Row("-", "a path-traversal dataset id", "404", str(traversal.status_code), traversal.status_code == 404),
            Row("6", "GET /extrinsics?format=urdf&camera_frame=a\"><x", "422",
                f"{export.status_code} (a version stored: {bad_frame.status_code})", export.status_code == 422)]


# -- a full disk ----------------------------------------------------------------------------------------------------
@contextlib.contextmanager
def tmpfs(where: Path, size: str) -> Iterator[Path]:
    where.mkdir(parents=True, exist_ok=True)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)], check=True)
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def fill(mount: Path) -> Path:
    """A file taking every free byte of ``mount``."""
    filler = mount / f"filler-{time.monotonic_ns()}"
    with filler.open("wb", buffering=0) as fh:
        for size in (1 << 20, 1 << 12, 1):
            try:
                while True:
                    fh.write(bytes(size))
            except OSError as exc:
                if exc.errno != errno.ENOSPC:
                    raise
    return filler


SIM_RIG = {"scene": "indoor", "seed": 5, "stops": 12, "still_s": 2.5, "move_s": 1.0, "width": 256, "height": 128}


def rig_file(p: Probe) -> Path:
    (p.root / "sim.yaml").write_text(yaml.safe_dump(SIM_RIG))
    path = p.root / "rig.yaml"
    path.write_text(yaml.safe_dump({
        "camera": {"model": "equirectangular", "width": 256, "height": 128, "source": f"sim:{p.root / 'sim.yaml'}"},
        "lidar": {"model": "VLP-16", "source": f"sim:{p.root / 'sim.yaml'}"},
        "capture": {"n": 12, "still_seconds": 0.5, "sweeps": 2}}))
    return path


def nothing_queued_on_a_full_disk(p: Probe, served: Served, mount: Path) -> list[Row]:
    filler = fill(mount)
    answers = [served.client.post("/calibrate", json=calibrate_body(p)) for _ in range(5)]
    capture = served.client.post("/capture", json={"dataset": "ds2", "source": "sim"})
    version = served.client.post("/extrinsics/versions", json={"T_camera_lidar": {"rpy_deg": [0, 0, 0],
                                                                                  "xyz_m": [0, 0, 0]}})
    left = [j["id"] for j in served.client.get("/jobs").json() if not finished(j)]
    filler.unlink()
    again = served.client.post("/calibrate", json=calibrate_body(p))
    job = served.wait(again.json()["id"], finished, 600) if again.status_code == 202 else {}
    codes = [a.status_code for a in answers]
    return [
        Row("7", "5 x POST /calibrate and a POST /capture on a full 12 MB tmpfs",
            "507 naming the path and free space; nothing queued", f"{codes}, capture {capture.status_code}, "
            f"unfinished jobs {left}: {answers[0].json()['detail'][:70]}",
            codes == [507] * 5 and capture.status_code == 507 and not left),
        Row("9", "POST /extrinsics/versions on the full disk", "201 or 507, never 500", str(version.status_code),
            version.status_code in (201, 507)),
        Row("7", "the space freed: POST /calibrate, no restart", "202, and the job succeeds",
            f"{again.status_code}, job {job.get('status')}",
            again.status_code == 202 and job.get("status") == "succeeded"),
    ]


def disk_fills_under_jobs(p: Probe, served: Served, mount: Path) -> list[Row]:
    job_id = served.client.post("/calibrate", json={**calibrate_body(p), "auto_activate": True}).json()["id"]
    served.wait(job_id, lambda j: j["status"] == "running" and j["fraction"] > 0.05 or finished(j))
    filler = fill(mount)
    job = served.wait(job_id, finished, 600)
    cancel = served.client.delete(f"/jobs/{job_id}").status_code
    filler.unlink()
    capture_id = served.client.post("/capture", json={"dataset": "cap", "source": "sim", "n": 12}).json()["id"]
    running = served.wait(capture_id, lambda j: j["fraction"] > 0 or finished(j), 300)
    filler = fill(mount)
    captured = served.wait(capture_id, finished, 300)
    filler.unlink()
    next_capture = served.client.post("/capture", json={"dataset": "cap2", "source": "sim", "n": 1})
    return [
        Row("8", "the disk fills under a running calibration", "it ends (no 'running'/'cancelling'); DELETE 409",
            f"{job['status']}: {(job['error'] or '')[:70]}; DELETE {cancel}", finished(job) and cancel == 409),
        Row("8", "the disk fills under a running capture", "it fails naming the disk; the sensors free again",
            f"{captured['status']} after {running['stage']!r}: {(captured['error'] or '')[:70]}; next capture "
            f"{next_capture.status_code}", captured["status"] == "failed" and next_capture.status_code == 202),
    ]


def full_disk(p: Probe) -> list[Row]:
    if os.geteuid() != 0:
        return [Row("7-9", "full-disk attempts on a tmpfs", "-", "not run: mounting a tmpfs needs root", None)]
    rows = []
    # 12 MB as the probe had it; 32 MB for the jobs that run until it fills (a capture keeps 6.4 MB free)
    for size, attempt in (("12m", nothing_queued_on_a_full_disk), ("32m", disk_fills_under_jobs)):
        with tmpfs(p.root / f"disk-{size}", size) as mount:
            served = Served(service_data(p, mount), {"RIGD_MIN_FREE_MB": "1", "RIGD_CONFIG": str(rig_file(p))})
            try:
                rows += attempt(p, served, mount)
            finally:
                served.end()
    return rows


def no_floor_on_a_full_disk(p: Probe) -> Row:
    """RIGD_MIN_FREE_MB=0: the disk itself refuses (SQLite, the job's folder), as the probe found the service."""
    if os.geteuid() != 0:
        return Row("7", "the full disk with no free-space floor", "-", "not run: mounting a tmpfs needs root", None)
    with tmpfs(p.root / "nofloor", "12m") as mount:
        served = Served(service_data(p, mount), {"RIGD_MIN_FREE_MB": "0"})
        try:
            filler = fill(mount)
            codes = [served.client.post("/calibrate", json=calibrate_body(p)).status_code for _ in range(5)]
            jobs = [j["id"] for j in served.client.get("/jobs").json()]
            ended = [served.wait(j, finished, 300)["status"] for j in jobs]
            filler.unlink()
            again = served.client.post("/calibrate", json=calibrate_body(p))
            capture = served.client.post("/capture", json={"dataset": "c", "source": "sim", "n": 1}).status_code
        finally:
            served.end()
    return Row("7", "RIGD_MIN_FREE_MB=0: 5 x POST /calibrate on the full disk, then space freed",
               "each 507 or a job that ends; then 202 (no 429, no 409)",
               f"{codes}, jobs {dict(zip(jobs, ended, strict=True))}; then calibrate {again.status_code}, "
               f"capture {capture}",
               all(c in (200, 202, 507) for c in codes) and again.status_code in (200, 202) and capture == 202)


def lidar_export_on_a_full_disk(p: Probe) -> Row:
    if os.geteuid() != 0:
        return Row("11", "lidar export --out on a full disk", "-", "not run: mounting a tmpfs needs root", None)
    with tmpfs(p.root / "tiny", "256k") as mount:
        code, err = p.rigd("lidar", "export", "--any-product", str(LEGACY_PCAP), "--out", str(mount / "out"))
        left = sorted(f.name for f in mount.iterdir())
    return Row("11", "lidar export --out on a 256 kB tmpfs", "exit 74 with the free space, nothing left",
               said(code, err), named(code, err, 74) and "MB free" in err and not left)


def no_writable_home(p: Probe) -> Row:
    return Row("11", "rigd --version with no writable HOME nor NUMBA_CACHE_DIR", "prints the version",
               "not run: as root every folder is writable (tests/rigd/test_cli_errors.py checks the fallback)", None)


# -- the table ------------------------------------------------------------------------------------------------------
GROUPS: dict[str, list[Callable[..., Row | list[Row]]]] = {
    "CLI": [export_over_its_input, calibrate_twice_into_one_out, lidar_export_over_another, head_hash_covers_images,
            launch_file_injection, bad_datasets, check_error_is_not_drift, damaged_database, thinning, corrupt_pcap,
            no_writable_home],
    "SERVICE": [kill_between_version_and_job, capture_while_calibrating, cheap_refusals],
    "DISK": [full_disk, no_floor_on_a_full_disk, lidar_export_on_a_full_disk],
}


def print_table(rows: list[Row]) -> None:
    print("| # | attempt | expected | got | verdict |")
    print("|---|---|---|---|---|")
    for row in rows:
        verdict = "not run" if row.ok is None else "ok" if row.ok else "FAILED"
        got = row.got.replace("|", "\\|").replace("\n", " ")
        print(f"| {row.finding} | {row.attempt.replace('|', '/')} | {row.expected} | {got} | {verdict} |")
    counts = [sum(r.ok is v for r in rows) for v in (True, False, None)]
    print(f"\n{counts[0]} ok, {counts[1]} FAILED, {counts[2]} not run, of {len(rows)} attempts")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=4, help="kill -9 rounds of finding 1 (default 4)")
    parser.add_argument("--only", choices=sorted(GROUPS), default=None, help="one group of attempts")
    args = parser.parse_args()
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        probe = Probe(Path(tmp))
        for name, attempts in GROUPS.items():
            for attempt in attempts if args.only in (None, name) else []:
                started = time.monotonic()
                found = attempt(probe, args.rounds) if attempt is kill_between_version_and_job else attempt(probe)
                rows.extend(found if isinstance(found, list) else [found])
                print(f"[{time.monotonic() - started:6.1f} s] {attempt.__name__}", file=sys.stderr, flush=True)
    print_table(rows)


if __name__ == "__main__":
    main()
