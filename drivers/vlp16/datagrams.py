"""A batch of received UDP datagrams sorted by port: the common output of the pcap reader and the receiver."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.layout import DATA_PACKET_SIZE
from drivers.vlp16.validate import PacketFault


class PositionDatagram(NamedTuple):
    """A 512-byte payload from the position port, its host time s and stream datagram (or record) number."""

    payload: bytes
    host_s: float
    number: int


@dataclass(frozen=True)
class DatagramBatch:
    """Datagrams in arrival order. ``data`` (K,1206) uint8 data-port payloads of the right size, with
    ``data_host_s`` (K,) float64 s and ``data_index`` (K,) int64 stream datagram (or pcap record) index;
    ``faults`` lists (fault, count, first index) found before decoding; ``other`` counts other traffic;
    ``fragments`` the fragments of IPv4 datagrams, skipped as they are not reassembled (a VLP-16 never
    fragments, so they are someone else's traffic or a capture taken behind a fragmenting link)."""

    data: NDArray[np.uint8] = field(default_factory=lambda: np.empty((0, DATA_PACKET_SIZE), np.uint8))
    data_host_s: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    data_index: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, np.int64))
    positions: tuple[PositionDatagram, ...] = ()
    faults: tuple[tuple[PacketFault, int, int], ...] = ()
    other: int = 0
    fragments: int = 0


def fault_entry(fault: PacketFault, indices: NDArray[np.int64]) -> tuple[tuple[PacketFault, int, int], ...]:
    """``((fault, count, first index),)`` for a non-empty (n,) index array, else ``()``."""
    return ((fault, len(indices), int(indices.min())),) if len(indices) else ()
