"""VLP-16 decode throughput: rigd's driver against velodyne-decoder 3.1.0 on the legacy VeloView capture.

Both go from the pcap file to point clouds of whole rotations, in the same process, alternating, best
of N runs. velodyne-decoder refuses the file's legacy product id (0x21), so it reads a copy with byte
1205 set to 0x22; rigd reads the original with the product check off. Prints points/s, the ratio and the
multiple of real time (capture duration / decode time). Run: .venv/bin/python benchmarks/vlp16_decode.py
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import dpkt
import numpy as np
import velodyne_decoder as vd

from drivers.vlp16 import PcapReplay, Vlp16Config, decode_packets, read_batches

REPO = Path(__file__).resolve().parents[1]
LEGACY = REPO / "tests" / "data" / "vlp16" / "vlp16_legacyfw_1200rpm_50rot.pcap"


def patched_copy(source: Path, target: Path) -> None:
    """Copy a capture, writing product id 0x22 into every 1206-byte payload (the last frame byte)."""
    with source.open("rb") as src, target.open("wb") as dst:
        writer = dpkt.pcap.Writer(dst, snaplen=65535)
        for stamp, frame in dpkt.pcap.Reader(src):
            if len(frame) == 14 + 20 + 8 + 1206:
                frame = frame[:-1] + b"\x22"
            writer.writepkt(frame, ts=stamp)


def best_times(runs: dict[str, Callable[[], int]], repeats: int) -> dict[str, tuple[float, int]]:
    """Best time and point count of each run, alternating the runs so that all see the same machine load."""
    best: dict[str, tuple[float, int]] = {name: (float("inf"), 0) for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            start = time.perf_counter()
            points = run()
            best[name] = (min(best[name][0], time.perf_counter() - start), points)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pcap", type=Path, default=LEGACY)
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        peer_file = Path(tmp) / "patched.pcap"
        patched_copy(args.pcap, peer_file)
        config = Vlp16Config(product_ids=None)
        sweeps = list(PcapReplay(args.pcap, config))
        duration_s = sweeps[-1].end.device - sweeps[0].start.device

        def ours() -> int:
            return sum(len(s.points) for s in PcapReplay(args.pcap, config))

        def peer() -> int:
            peer_config = vd.Config(model=vd.Model.VLP16)
            return sum(len(points) for _, points in vd.read_pcap(str(peer_file), peer_config))

        payloads = np.concatenate([b.data for b in read_batches(args.pcap)])

        def decode_only() -> int:
            return len(decode_packets(payloads).points)

        runs = {"rigd": ours, "velodyne_decoder": peer, "rigd decode_packets only": decode_only}
        results = best_times(runs, args.repeats)

    print(f"capture: {args.pcap.name}, {duration_s:.3f} s of data, {len(payloads)} data packets")
    for name, (seconds, points) in results.items():
        print(
            f"{name:26s} {points:8d} points in {seconds * 1e3:7.2f} ms = "
            f"{points / seconds / 1e6:6.2f} Mpoints/s, {duration_s / seconds:6.1f}x real time"
        )
    ratio = (results["rigd"][1] / results["rigd"][0]) / (
        results["velodyne_decoder"][1] / results["velodyne_decoder"][0]
    )
    print(f"ratio rigd / velodyne_decoder (file to sweeps, points per second): {ratio:.2f}x")


if __name__ == "__main__":
    main()
