"""Vectorised decoding of whole buffers of VLP-16 data packets into points (docs/vlp16.md).

Azimuth of a firing: the block azimuth plus the packet's mean rotation rate (first to last block azimuth)
times the firing's delay in the block, rounded to 0.01 deg. This is velodyne_decoder's arithmetic, done
in float32 in the same order so that ties round the same way.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.calibration import LaserCalibration
from drivers.vlp16.layout import (
    AZIMUTH_UNITS,
    BLOCKS_PER_PACKET,
    CHANNELS_PER_BLOCK,
    DISTANCE_UNIT_M,
    FIRING_US,
    LASERS,
    SEQUENCE_US,
    ReturnMode,
    ReturnType,
    as_packet_records,
)

#: One decoded point. x y z m (ROS frame), intensity = reflectivity 0..255, time s (see decode_packets),
#: ring = elevation rank 0 = lowest, azimuth deg [0, 360) clockwise from above, return_type = ReturnType.
POINT_DTYPE = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "time", "ring", "azimuth", "return_type"],
        "formats": ["<f4", "<f4", "<f4", "u1", "<f8", "u1", "<f4", "u1"],
        "offsets": [0, 4, 8, 24, 16, 25, 12, 26],
        "itemsize": 32,
    }
)

def _firing_delays() -> NDArray[np.float32]:
    """(2,12,32) float32 s: delay of each channel after the packet timestamp, [single, dual] return modes."""
    block = np.arange(BLOCKS_PER_PACKET)[:, None]
    channel = np.arange(CHANNELS_PER_BLOCK)[None, :]
    single_seq = 2 * block + channel // LASERS
    dual_seq = 2 * (block // 2) + channel // LASERS  # a dual block pair shares its firings
    seq = np.stack([single_seq, dual_seq])
    return ((seq * SEQUENCE_US + (channel % LASERS) * FIRING_US) * 1e-6).astype(np.float32)


_DELAY_S = _firing_delays()
# Delay of each channel after its own block's first firing (the block azimuth's instant).
_DELAY_IN_BLOCK_S = (_DELAY_S - _DELAY_S[:, :, :1]).astype(np.float32)
# Time from block 0 to the last block's azimuth (block 11, or pair 5 in dual mode), as the peer computes it.
_SPAN_S = np.array(
    [_DELAY_S[0, 11, 0] - _DELAY_S[0, 0, 0], _DELAY_S[0, 5, 0] - _DELAY_S[0, 0, 0]], np.float32
)
# Tables over three turns so that an azimuth in units + one turn indexes them without a modulo.
_TURNS = np.arange(3 * AZIMUTH_UNITS) % AZIMUTH_UNITS
_COS_AZ = np.cos(np.radians(_TURNS / 100.0)).astype(np.float32)
_NEG_SIN_AZ = -np.sin(np.radians(_TURNS / 100.0)).astype(np.float32)
_AZ_DEG = (_TURNS / 100.0).astype(np.float32)
# return_type by [mode code (strongest, last, dual), block]: dual even blocks hold the last return.
_RETURN_TYPE = np.array(
    [[ReturnType.STRONGEST] * 12, [ReturnType.LAST] * 12, [ReturnType.LAST, ReturnType.STRONGEST] * 6],
    dtype=np.uint8,
)


class Decoded(NamedTuple):
    """``points`` (N,) POINT_DTYPE in packet, block, channel order; ``points_per_block`` (P,12) int64."""

    points: np.ndarray
    points_per_block: NDArray[np.int64]


def _keep_mask(
    distance: np.ndarray, reflectivity: np.ndarray, dual: NDArray[np.bool_]
) -> tuple[NDArray[np.bool_], NDArray[np.bool_] | None]:
    """(P,12,32) returns to keep (nonzero, not a repeated dual return) and (P,12,32) merged dual returns
    (None without dual-return packets)."""
    keep = distance != 0
    if not dual.any():
        return keep, None
    same = (distance[:, 0::2] == distance[:, 1::2]) & (reflectivity[:, 0::2] == reflectivity[:, 1::2])
    merged = np.zeros_like(keep)
    merged[:, 0::2] = same & dual[:, None, None] & keep[:, 0::2]
    keep[:, 1::2] &= ~merged[:, 0::2]
    return keep, merged


def _per_mode(table: np.ndarray, mode_index: NDArray[np.intp]) -> np.ndarray:
    """``table[mode_index]`` per packet, or the one table broadcast when all packets share a mode."""
    if len(mode_index) and np.all(mode_index == mode_index[0]):
        return np.asarray(table[mode_index[0]][None])
    return np.asarray(table[mode_index])


_CHUNK_PACKETS = 256  # packets decoded together: their temporaries stay in the CPU cache


class _LaserTables(NamedTuple):
    """Per-channel (32,) tables: cos and sin of the elevation (float32), z offset m (float32), ring."""

    cos_w: NDArray[np.float32]
    sin_w: NDArray[np.float32]
    z_offset: NDArray[np.float32]
    ring: NDArray[np.uint8]

    @classmethod
    def of(cls, calibration: LaserCalibration) -> _LaserTables:
        elevation = np.radians(calibration.elevation_deg)
        return cls(
            np.tile(np.cos(elevation).astype(np.float32), 2),
            np.tile(np.sin(elevation).astype(np.float32), 2),
            np.tile(calibration.vertical_offset_m.astype(np.float32), 2),
            np.tile(calibration.ring_of_laser, 2),
        )


def decode_packets(
    payloads: NDArray[np.uint8],
    calibration: LaserCalibration | None = None,
    packet_time_s: NDArray[np.float64] | None = None,
) -> Decoded:
    """Decode (P,1206) uint8 payloads of *valid* data packets (see :func:`check_packets`).

    ``time`` of a point is ``packet_time_s[p]`` plus its firing delay, s; ``packet_time_s`` (P,) float64
    defaults to each packet's own timestamp, seconds past the hour. Returns with distance 0 are dropped;
    in dual-return mode a repeated return (same distance and reflectivity in both blocks) is kept once,
    with return_type BOTH.
    """
    records = as_packet_records(payloads)
    channels = records["blocks"]["channels"]
    dual = records["return_mode"] == ReturnMode.DUAL
    if packet_time_s is None:
        packet_time_s = records["timestamp_us"] * 1e-6
    packet_time_s = np.asarray(packet_time_s, dtype=np.float64)
    keep, merged = _keep_mask(channels["distance"], channels["reflectivity"], dual)
    per_block = keep.sum(axis=2)
    offsets = np.concatenate([[0], np.cumsum(per_block.sum(axis=1))])
    points = np.empty(offsets[-1], dtype=POINT_DTYPE)
    tables = _LaserTables.of(calibration or LaserCalibration())
    for start in range(0, len(records), _CHUNK_PACKETS):
        chunk = slice(start, start + _CHUNK_PACKETS)
        _decode_into(
            points[offsets[start] : offsets[min(start + _CHUNK_PACKETS, len(records))]],
            records[chunk],
            keep[chunk],
            None if merged is None else merged[chunk],
            packet_time_s[chunk],
            tables,
        )
    return Decoded(points, per_block)


def _decode_into(
    out: np.ndarray,
    records: np.ndarray,
    keep: NDArray[np.bool_],
    merged: NDArray[np.bool_] | None,
    packet_time_s: NDArray[np.float64],
    tables: _LaserTables,
) -> None:
    """Fill ``out`` with the kept returns of a few packets."""
    blocks = records["blocks"]
    mode = records["return_mode"]
    dual = mode == ReturnMode.DUAL
    dual_index = dual.astype(np.intp)

    azimuth = blocks["azimuth"]
    span = ((azimuth[:, -1].astype(np.int32) - azimuth[:, 0]) % AZIMUTH_UNITS).astype(np.float32)
    rate = span / _SPAN_S[dual_index]  # azimuth units per second, float32 like the peer
    shifted = rate[:, None, None] * _per_mode(_DELAY_IN_BLOCK_S, dual_index)
    np.add(azimuth.astype(np.float32)[:, :, None], shifted, out=shifted)  # the peer's order of operations
    shifted += np.float32(AZIMUTH_UNITS)
    shifted += np.float32(0.5)  # exact in float32 here, so floor(x + 0.5) is lround(x)
    az_units = np.floor(shifted, out=shifted).astype(np.intp)[keep]

    r = blocks["channels"]["distance"].astype(np.float32)
    r *= np.float32(DISTANCE_UNIT_M)
    xy = (r * tables.cos_w)[keep]
    out["x"] = xy * _COS_AZ[az_units]
    out["y"] = xy * _NEG_SIN_AZ[az_units]
    r *= tables.sin_w
    r += tables.z_offset
    out["z"] = r[keep]
    out["intensity"] = blocks["channels"]["reflectivity"][keep]
    time = packet_time_s[:, None, None] + _per_mode(_DELAY_S, dual_index)
    out["time"] = np.broadcast_to(time, keep.shape)[keep]
    out["ring"] = np.broadcast_to(tables.ring, keep.shape)[keep]
    out["azimuth"] = _AZ_DEG[az_units]
    mode_code = np.select([mode == ReturnMode.LAST, dual], [1, 2], 0)
    return_type = np.broadcast_to(_per_mode(_RETURN_TYPE, mode_code)[:, :, None], keep.shape)
    if merged is not None:
        return_type = np.where(merged, np.uint8(ReturnType.BOTH), return_type)
    out["return_type"] = return_type[keep]
