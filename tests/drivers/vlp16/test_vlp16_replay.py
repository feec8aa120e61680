"""File replay: real-time pacing and the port filter."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from vlp16_helpers import synthetic_firings

from drivers.vlp16 import PcapReplay, Ports, encode_data_packets, write_pcap


def capture(tmp_path: Path, port: int, turns: float = 2.5) -> Path:
    f = synthetic_firings(int(turns * 0.1 / 55.296e-6), start_deg=300.0)
    packets = encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 100.0)
    path = tmp_path / f"port{port}.pcap"
    write_pcap(
        path, [(float(t), port, p.tobytes()) for t, p in zip(packets.time_s, packets.payloads, strict=True)]
    )
    return path


def test_real_time_pacing_follows_the_capture_clock(tmp_path: Path) -> None:
    path = capture(tmp_path, 2368)
    fast = list(PcapReplay(path))
    span_s = fast[-1].end.host - fast[0].end.host  # sweeps are released at their last packet's time
    assert span_s > 0.2
    started = time.monotonic()
    paced = list(PcapReplay(path, speed=2.0))
    elapsed = time.monotonic() - started
    assert span_s / 2.0 - 0.01 <= elapsed < span_s / 2.0 + 1.0
    assert [len(s.points) for s in paced] == [len(s.points) for s in fast]


def test_only_the_configured_ports_are_decoded(tmp_path: Path) -> None:
    path = capture(tmp_path, 2369)
    default = PcapReplay(path)
    assert list(default) == [] and default.stats.data_packets == 0
    assert default.stats.other_datagrams == default.summary.records > 0
    moved = PcapReplay(path, ports=Ports(data=2369))
    sweeps = list(moved)
    assert moved.stats.data_packets == moved.summary.records and moved.stats.other_datagrams == 0
    assert sum(len(s.points) for s in sweeps) > 0 and np.all([s.missing_packets == 0 for s in sweeps])
