"""The live UDP receiver over loopback (127.0.0.1, OS-chosen ports); every wait is bounded."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Iterable

import numpy as np
import pytest
from vlp16_helpers import LEGACY_PCAP, synthetic_firings

from drivers.vlp16 import (
    PacketFault,
    PcapReplay,
    Ports,
    UdpReceiver,
    Vlp16Config,
    encode_data_packets,
    send_datagrams,
)
from drivers.vlp16.errors import ReceiverError
from drivers.vlp16.pcap import read_datagrams

LEGACY = Vlp16Config(product_ids=None)


def receive_while_sending(receiver: UdpReceiver, datagrams: Iterable[tuple[float, int, bytes]],
                          speed: float | None) -> list:
    """Send from a thread, collect sweeps until 0.5 s without datagrams (20 s at most)."""
    sender = threading.Thread(target=send_datagrams, args=(list(datagrams), "127.0.0.1", speed))
    sender.start()
    try:
        return list(receiver.sweeps(timeout_s=20.0, idle_s=0.5))
    finally:
        sender.join(timeout=20.0)
        assert not sender.is_alive()


def on_ports(datagrams: Iterable[tuple[float, int, bytes]], ports: Ports) -> list[tuple[float, int, bytes]]:
    """Redirect the sensor's ports (2368/8308) to the receiver's OS-chosen ones."""
    mapping = {2368: ports.data, 8308: ports.position}
    return [(t, mapping[port], payload) for t, port, payload in datagrams]


def test_pcap_replayed_over_udp_at_the_sensor_rate_gives_the_file_sweeps() -> None:
    expected = list(PcapReplay(LEGACY_PCAP, LEGACY))
    with UdpReceiver(LEGACY, host="127.0.0.1", ports=Ports(0, 0)) as receiver:
        assert receiver.ports.data > 0 and receiver.ports.position > 0
        started = time.monotonic()
        sweeps = receive_while_sending(receiver, on_ports(read_datagrams(LEGACY_PCAP), receiver.ports), 1.0)
        elapsed = time.monotonic() - started
        stats = receiver.stats
    assert elapsed > 2.4  # 2.52 s of capture, sent at the sensor's pace
    assert stats.data_packets == 1902 and stats.position_packets == 367
    assert stats.missing_packets == 0 and stats.overruns == 0 and stats.bad_packets == 0
    assert len(sweeps) == len(expected) == 52
    for ours, file_sweep in zip(sweeps, expected, strict=True):
        assert np.array_equal(ours.points, file_sweep.points)
        # Device time is anchored to the hour of the host clock, which differs between now and 2014.
        assert (ours.start.device - file_sweep.start.device) % 3600.0 == pytest.approx(0.0, abs=1e-6)
        assert ours.complete == file_sweep.complete and ours.packet_count == file_sweep.packet_count


def synthetic_stream(turns: float = 3.0):
    f = synthetic_firings(int(turns * 0.1 / 55.296e-6), start_deg=50.0)
    return encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 5000.0)


def test_dropped_reordered_and_garbage_datagrams_are_reported() -> None:
    packets = synthetic_stream()
    count = len(packets.payloads)
    dropped = [17, 18, 100, 171]
    order = [i for i in range(count) if i not in dropped]
    for i in range(5, len(order) - 1, 9):  # swap neighbours: reordering inside the receiver's window
        order[i], order[i + 1] = order[i + 1], order[i]
    garbage = [b"\xde\xad", b"x" * 1206, bytes(1300)]
    with UdpReceiver(host="127.0.0.1", ports=Ports(0, 0)) as receiver:
        port = receiver.ports.data
        datagrams = [(float(packets.time_s[i]), port, packets.payloads[i].tobytes()) for i in order]
        datagrams[50:50] = [(float(packets.time_s[50]), receiver.ports.data, g) for g in garbage]
        sweeps = receive_while_sending(receiver, datagrams, speed=4.0)
        stats = receiver.stats
    assert stats.missing_packets == len(dropped) == sum(s.missing_packets for s in sweeps)
    assert stats.data_packets == count - len(dropped)
    assert stats.faults == {PacketFault.SIZE: 2, PacketFault.FLAG: 1}
    assert stats.first_fault == {PacketFault.SIZE: 50, PacketFault.FLAG: 51}
    assert stats.overruns == 0
    channels = packets.payloads[:, :1200].reshape(count, 12, 100)[:, :, 4:].reshape(count, 12, 32, 3)
    returns = np.count_nonzero(channels[:, :, :, :2].any(axis=3), axis=(1, 2))  # nonzero distance bytes
    assert sum(len(s.points) for s in sweeps) == returns.sum() - returns[dropped].sum()


def test_a_consumer_that_falls_behind_gets_overruns_not_a_blocked_socket() -> None:
    packets = synthetic_stream(0.5)
    receiver = UdpReceiver(host="127.0.0.1", ports=Ports(0, 0), queue_batches=1, batch_packets=1)
    with receiver:
        send_datagrams([(0.0, receiver.ports.data, p.tobytes()) for p in packets.payloads], speed=None)
        deadline = time.monotonic() + 5.0
        while receiver.overruns + 1 < len(packets.payloads) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert receiver.overruns == len(packets.payloads) - 1  # one batch of one packet fits the queue
        sweeps = list(receiver.sweeps(timeout_s=0.5))
    assert sum(s.packet_count for s in sweeps) == 1
    assert receiver.stats.overruns == len(packets.payloads) - 1


def test_lifecycle_errors_and_clean_shutdown() -> None:
    receiver = UdpReceiver(host="127.0.0.1", ports=Ports(0, 0))
    with pytest.raises(ReceiverError, match="start"):
        next(receiver.sweeps(timeout_s=0.1))
    receiver.start()
    thread = receiver._thread
    assert thread is not None and thread.is_alive()
    receiver.close()
    receiver.close()
    assert not thread.is_alive()
    assert list(receiver.sweeps(timeout_s=1.0)) == []  # closed: ends at once, nothing pending
    with pytest.raises(ReceiverError, match="once"):
        receiver.start()
    with pytest.raises(ReceiverError, match="cannot bind 203.0.113.7"):
        UdpReceiver(host="203.0.113.7", ports=Ports(0, 0)).start()  # an address this host does not have


HOLD_PORT = """
import socket, sys, time
sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
if sys.argv[1] == "reuse":
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
sock.bind(("0.0.0.0", 0))
print(sock.getsockname()[1], flush=True)
time.sleep(60)
"""


@pytest.mark.parametrize("holder", ["plain", "reuse"])
def test_a_port_bound_by_another_process_is_refused_naming_it(holder: str) -> None:
    # Another receiver (with SO_REUSEADDR, as rigd's set it: then Linux let a second one bind and take the packets).
    other = subprocess.Popen([sys.executable, "-c", HOLD_PORT, holder], stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout is not None
        port = int(other.stdout.readline())
        for host in ("0.0.0.0", "127.0.0.1"):
            with pytest.raises(ReceiverError, match=rf"port {port} is in use by another process \(pid {other.pid}: "):
                UdpReceiver(host=host, ports=Ports(port, 0)).start()
    finally:
        other.kill()
        other.wait(10)
    with UdpReceiver(host="127.0.0.1", ports=Ports(port, 0)) as receiver:  # free again
        assert receiver.ports.data == port
