"""VLP-16 packet layout and constants (VLP-16 user manual 63-9243; all fields little-endian).

Data packet (1206-byte UDP payload, port 2368): 12 blocks of 100 bytes, then a uint32 timestamp
(microseconds past the hour, first firing of block 0), the return-mode byte and the product-id byte.
A block is flag ``FF EE``, azimuth uint16 (0.01 deg), then 32 channels of (distance uint16 in 2 mm,
reflectivity uint8). Channels 0-15 are the block's first 16-laser firing sequence, 16-31 the second.

Position packet (512-byte payload, port 8308): timestamp uint32 at 198, PPS status at 202,
NUL-terminated NMEA ``$GPRMC`` sentence from 206.
"""

from __future__ import annotations

from enum import IntEnum, IntFlag

import numpy as np

DATA_PACKET_SIZE = 1206
POSITION_PACKET_SIZE = 512
DATA_PORT = 2368
POSITION_PORT = 8308

BLOCKS_PER_PACKET = 12
CHANNELS_PER_BLOCK = 32
LASERS = 16
BLOCK_FLAG = 0xEEFF  # bytes FF EE read as uint16 LE
AZIMUTH_UNITS = 36000  # 0.01 deg per unit, one turn
DISTANCE_UNIT_M = 0.002
MAX_DISTANCE_M = 0xFFFF * DISTANCE_UNIT_M

FIRING_US = 2.304  # one laser firing
SEQUENCE_US = 55.296  # 16 firings + recharge
SINGLE_SEQUENCES = 2 * BLOCKS_PER_PACKET  # firing sequences per packet in single-return modes
DUAL_SEQUENCES = BLOCKS_PER_PACKET  # block pairs repeat a sequence in dual-return mode
HOUR_US = 3_600_000_000

VLP16_PRODUCT_ID = 0x22
# Pre-2015 VLP-16 firmware writes the HDL-32E id; accept it only when asked (docs/vlp16.md).
LEGACY_PRODUCT_ID = 0x21

#: Nominal elevation of lasers 0..15 in degrees (manual table 9-1).
NOMINAL_ELEVATION_DEG = np.array(
    [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15], dtype=np.float64
)

CHANNEL_DTYPE = np.dtype([("distance", "<u2"), ("reflectivity", "u1")])
BLOCK_DTYPE = np.dtype(
    [("flag", "<u2"), ("azimuth", "<u2"), ("channels", CHANNEL_DTYPE, (CHANNELS_PER_BLOCK,))]
)
DATA_PACKET_DTYPE = np.dtype(
    [
        ("blocks", BLOCK_DTYPE, (BLOCKS_PER_PACKET,)),
        ("timestamp_us", "<u4"),
        ("return_mode", "u1"),
        ("product_id", "u1"),
    ]
)
assert DATA_PACKET_DTYPE.itemsize == DATA_PACKET_SIZE

POSITION_TIMESTAMP_OFFSET = 198
POSITION_PPS_OFFSET = 202
POSITION_NMEA_OFFSET = 206


class ReturnMode(IntEnum):
    """Byte 1204 of a data packet."""

    STRONGEST = 0x37
    LAST = 0x38
    DUAL = 0x39

    @property
    def sequences_per_packet(self) -> int:
        return DUAL_SEQUENCES if self is ReturnMode.DUAL else SINGLE_SEQUENCES

    @property
    def packet_period_us(self) -> float:
        """Nominal spacing of packets: 1327.104 us single return, 663.552 us dual."""
        return self.sequences_per_packet * SEQUENCE_US


class ReturnType(IntFlag):
    """Per-point ``return_type`` column; same values as velodyne_decoder's ReturnMode (BOTH = 3)."""

    STRONGEST = 1
    LAST = 2
    BOTH = 3


class PpsStatus(IntEnum):
    """Byte 202 of a position packet."""

    ABSENT = 0
    SYNCHRONISING = 1
    LOCKED = 2
    ERROR = 3


def as_packet_records(payloads: np.ndarray) -> np.ndarray:
    """View a (P,1206) uint8 array of data-packet payloads as (P,) records of ``DATA_PACKET_DTYPE``."""
    return (
        np.ascontiguousarray(payloads, dtype=np.uint8)
        .reshape(-1, DATA_PACKET_SIZE)
        .view(DATA_PACKET_DTYPE)[:, 0]
    )
