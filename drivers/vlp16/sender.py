"""Sending datagrams over UDP at their recorded pace: pcap replay to a live receiver, a simulated sensor."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterable


def send_datagrams(
    datagrams: Iterable[tuple[float, int, bytes]], host: str = "127.0.0.1", speed: float | None = 1.0,
    *, on_host_clock: bool = False,
) -> int:
    """Send (time s, destination port, payload) datagrams to ``host`` in order; returns how many were sent.

    With ``speed`` a datagram leaves at (its time - the first time) / speed after the first one (1.0 = the
    sensor's own rate); None sends as fast as possible. ``on_host_clock``: the times are host times
    (``time.time()``) and each datagram leaves at its own (at once if that has passed), as a sensor's packets
    leave on its clock: paced from the first one, a first send made late by a busy machine would make every
    later one as late, a clock offset the receiver rightly measures.
    """
    sent = 0
    origin: tuple[float, float] | None = None  # (first datagram time, wall clock when it was sent)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        for time_s, port, payload in datagrams:
            if on_host_clock:
                time.sleep(max(0.0, time_s - time.time()))
            elif speed is not None:
                origin = origin or (time_s, time.monotonic())
                delay = origin[1] + (time_s - origin[0]) / speed - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            sock.sendto(payload, (host, port))
            sent += 1
    return sent
