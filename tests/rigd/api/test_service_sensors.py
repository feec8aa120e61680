"""GET /status reports a live VLP-16 stream: packet rate, lost packets and PPS, probed over loopback UDP."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from api_helpers import Server, free_port, rig_file

from drivers.vlp16 import PpsStatus, encode_data_packets, encode_position_packet, send_datagrams

FIRING_S = 55.296e-6  # one firing sequence of the 16 lasers (VLP-16 manual)
PACKET_RATE_HZ = 1 / (24 * FIRING_S)  # 24 sequences per packet in strongest-return mode: 753.5 /s


def stream(data_port: int, position_port: int, seconds: float, drop_every: int):
    """(time, port, payload) of a 600 rpm stream with every ``drop_every``-th data packet left out, and a
    position packet with PPS locked every 0.1 s."""
    firings = int(seconds / FIRING_S)
    azimuth_deg = (np.arange(firings) * 360.0 * 10.0 * FIRING_S) % 360.0  # 10 turns per second
    packets = encode_data_packets(np.full((firings, 16), 10.0), np.full((firings, 16), 100), azimuth_deg, 1000.0)
    data = [(t, data_port, p.tobytes()) for i, (t, p) in enumerate(zip(packets.time_s, packets.payloads,
                                                                       strict=True)) if i % drop_every]
    positions = [(t, position_port, encode_position_packet(int(t * 1e6), PpsStatus.LOCKED))
                 for t in np.arange(packets.time_s[0], packets.time_s[-1], 0.1)]
    return sorted(data + positions, key=lambda d: d[0])


def test_status_shows_the_lidar_stream(tmp_path):
    data_port, position_port = free_port(), free_port()
    config = rig_file(tmp_path / "rig.yaml", lidar=f"udp:127.0.0.1:{data_port}:{position_port}")
    server = Server(tmp_path / "data", env={"RIGD_CONFIG": str(config), "RIGD_SENSOR_POLL_S": "1"}).start()
    datagrams = stream(data_port, position_port, seconds=3.0, drop_every=25)
    sender = threading.Thread(target=send_datagrams, args=(datagrams, "127.0.0.1", 1.0))
    sender.start()
    try:
        with server.client() as client:
            deadline = time.monotonic() + 20
            while (lidar := client.get("/status").json()["sensors"]["lidar"])["state"] != "ok":
                assert time.monotonic() < deadline, lidar
                time.sleep(0.2)
    finally:
        sender.join(timeout=30)
        server.stop()
    assert lidar["source"] == f"udp:127.0.0.1:{data_port}:{position_port}"
    assert lidar["pps"] == "locked"
    # 1 packet in 25 is missing: 96 % of the sensor's rate arrives, and the gaps are counted as lost.
    assert lidar["packet_rate_hz"] == pytest.approx(PACKET_RATE_HZ * 24 / 25, rel=0.1)
    assert lidar["packets_lost"] >= 20  # about 30 lost in the second listened to
