"""Packet validation: every bad packet is counted under one fault, with the index of the first one."""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.layout import AZIMUTH_UNITS, BLOCK_FLAG, HOUR_US, ReturnMode


class PacketFault(Enum):
    """Why a datagram was not decoded. Listed in the order the checks are applied."""

    FRAME = "capture record is not a decodable link-layer frame"
    TRUNCATED = "capture record cut short"
    SIZE = "wrong size"  # a datagram on the data/position port that is not 1206/512 bytes
    POSITION = "position packet with an invalid PPS byte or timestamp"
    FLAG = "block flag is not FF EE"
    AZIMUTH = "block azimuth > 36000"  # 36000 means 0 (written by old firmware)
    TIMESTAMP = "timestamp >= 3600 s past the hour"  # the device counts 0..3599999999 us past the hour
    RETURN_MODE = "unknown return mode byte"
    PRODUCT_ID = "unexpected product id"
    DUAL_PAIR = "dual-return block pair with different azimuths"
    DUPLICATE = "duplicate device timestamp"
    LATE = "arrived after its sweep was emitted"


_MODES = np.array([m.value for m in ReturnMode], dtype=np.uint8)


@dataclass(frozen=True)
class PacketCheck:
    """Result of :func:`check_packets`: ``valid`` (P,) bool; per fault a count and a first packet index."""

    valid: NDArray[np.bool_]
    counts: dict[PacketFault, int]
    first_index: dict[PacketFault, int]


def check_packets(records: np.ndarray, product_ids: Collection[int] | None) -> PacketCheck:
    """Check (P,) ``DATA_PACKET_DTYPE`` records: block flags, azimuths, timestamp, mode byte, product id, dual pairs.

    ``product_ids`` are the accepted values of byte 1205; None accepts any (legacy firmware).
    """
    blocks = records["blocks"]
    mode = records["return_mode"]
    tests: list[tuple[PacketFault, NDArray[np.bool_]]] = [
        (PacketFault.FLAG, np.any(blocks["flag"] != BLOCK_FLAG, axis=1)),
        (PacketFault.AZIMUTH, np.any(blocks["azimuth"] > AZIMUTH_UNITS, axis=1)),
        # Unwrapped modulo the hour, such a stamp would land minutes away and start a phantom sweep there.
        (PacketFault.TIMESTAMP, records["timestamp_us"] >= HOUR_US),
        (PacketFault.RETURN_MODE, ~np.isin(mode, _MODES)),
    ]
    if product_ids is not None:
        tests.append((PacketFault.PRODUCT_ID, ~np.isin(records["product_id"], list(product_ids))))
    azimuth = blocks["azimuth"]
    unpaired = np.any(azimuth[:, 0::2] != azimuth[:, 1::2], axis=1) & (mode == ReturnMode.DUAL)
    tests.append((PacketFault.DUAL_PAIR, unpaired))
    valid = np.ones(len(records), dtype=bool)
    counts: dict[PacketFault, int] = {}
    first: dict[PacketFault, int] = {}
    for fault, failed in tests:
        hit = np.flatnonzero(failed & valid)
        if len(hit):
            counts[fault] = len(hit)
            first[fault] = int(hit[0])
            valid[hit] = False
    return PacketCheck(valid, counts, first)


@dataclass
class FaultTally:
    """Running fault counts of a stream; ``first_index``: stream-wide datagram index of the first one."""

    counts: dict[PacketFault, int] = field(default_factory=dict)
    first_index: dict[PacketFault, int] = field(default_factory=dict)

    def add(self, fault: PacketFault, count: int, first_index: int) -> None:
        if count <= 0:
            return
        self.counts[fault] = self.counts.get(fault, 0) + count
        self.first_index.setdefault(fault, first_index)

    def add_check(self, check: PacketCheck, index_of: NDArray[np.int64]) -> None:
        """Merge a :class:`PacketCheck` whose packet ``i`` has stream index ``index_of[i]``."""
        for fault, count in check.counts.items():
            self.add(fault, count, int(index_of[check.first_index[fault]]))
