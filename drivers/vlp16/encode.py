"""Encoding firings into VLP-16 packets, for tests and the simulated rig (the inverse of decode_packets).

Input is one row per firing sequence: ``ranges_m`` (F,16) float m (0, negative or non-finite = no return),
``reflectivity`` (F,16) 0..255, ``azimuth_deg`` (F,) of each firing. A block holds two consecutive
firings and stores only the first one's azimuth; a packet holds 24 firings (12 in dual mode, where block
2k carries the last return and block 2k+1 the strongest). A trailing partial packet is padded with
no-return firings at the extrapolated azimuth.
"""

from __future__ import annotations

import struct
from datetime import UTC, datetime
from functools import reduce
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.errors import EncodeError
from drivers.vlp16.layout import (
    AZIMUTH_UNITS,
    BLOCK_FLAG,
    DATA_PACKET_DTYPE,
    DISTANCE_UNIT_M,
    HOUR_US,
    LASERS,
    MAX_DISTANCE_M,
    POSITION_NMEA_OFFSET,
    POSITION_PACKET_SIZE,
    POSITION_PPS_OFFSET,
    POSITION_TIMESTAMP_OFFSET,
    SEQUENCE_US,
    VLP16_PRODUCT_ID,
    PpsStatus,
    ReturnMode,
)


class EncodedPackets(NamedTuple):
    """``payloads`` (P,1206) uint8 and ``time_s`` (P,) float64: time of each packet's first firing, s."""

    payloads: NDArray[np.uint8]
    time_s: NDArray[np.float64]


def _distance_units(ranges_m: NDArray[np.float64]) -> NDArray[np.uint16]:
    """Ranges to 2 mm units; returns the sensor cannot report (<= 0, non-finite, > 131 m) become 0."""
    ok = np.isfinite(ranges_m) & (ranges_m > 0) & (ranges_m <= MAX_DISTANCE_M)
    units = np.rint(np.where(ok, ranges_m, 0.0) / DISTANCE_UNIT_M)
    return np.where(ok, np.maximum(units, 1), 0).astype(np.uint16)


def _checked(name: str, array: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    array = np.asarray(array)
    if array.shape != shape:
        raise EncodeError(f"encoder: {name} has shape {array.shape}, expected {shape}")
    return array


def _padded(array: np.ndarray, total: int, fill: float) -> np.ndarray:
    pad = [(0, total - len(array))] + [(0, 0)] * (array.ndim - 1)
    return np.pad(array, pad, constant_values=fill)


def _padded_azimuth(azimuth_deg: NDArray[np.float64], total: int) -> NDArray[np.float64]:
    steps = np.diff(azimuth_deg) % 360.0
    step = float(np.median(steps)) if len(steps) else 0.0
    extra = azimuth_deg[-1] + step * np.arange(1, total - len(azimuth_deg) + 1)
    return np.concatenate([azimuth_deg, extra])


def encode_data_packets(
    ranges_m: NDArray[np.float64],
    reflectivity: NDArray[np.integer],
    azimuth_deg: NDArray[np.float64],
    start_time_s: float,
    return_mode: ReturnMode = ReturnMode.STRONGEST,
    product_id: int = VLP16_PRODUCT_ID,
    last_ranges_m: NDArray[np.float64] | None = None,
    last_reflectivity: NDArray[np.integer] | None = None,
) -> EncodedPackets:
    """Encode F firings into ceil(F / firings per packet) data packets.

    ``start_time_s`` is the time of firing 0 (s since the epoch, or any clock: only its microseconds past
    the hour are written). In DUAL mode, ``ranges_m``/``reflectivity`` are the strongest returns and
    ``last_ranges_m``/``last_reflectivity`` (default: the same, i.e. one return per laser) the last ones.
    """
    azimuth_deg = np.asarray(azimuth_deg, dtype=np.float64)
    if azimuth_deg.ndim != 1 or len(azimuth_deg) == 0 or not np.all(np.isfinite(azimuth_deg)):
        raise EncodeError("encoder: azimuth_deg must be a non-empty (F,) array of finite degrees")
    firings = len(azimuth_deg)
    strongest = _distance_units(_checked("ranges_m", ranges_m, (firings, LASERS)).astype(np.float64))
    refl = _checked("reflectivity", reflectivity, (firings, LASERS))
    if refl.size and (refl.min() < 0 or refl.max() > 255):
        raise EncodeError("encoder: reflectivity must be in 0..255")
    last = (
        strongest
        if last_ranges_m is None
        else _distance_units(_checked("last_ranges_m", last_ranges_m, (firings, LASERS)).astype(np.float64))
    )
    last_refl = (
        refl
        if last_reflectivity is None
        else _checked("last_reflectivity", last_reflectivity, (firings, LASERS))
    )
    per_packet = return_mode.sequences_per_packet
    packets = -(-firings // per_packet)
    total = packets * per_packet
    azimuth = np.rint(_padded_azimuth(azimuth_deg, total) * 100.0).astype(np.int64) % AZIMUTH_UNITS

    records = np.zeros(packets, dtype=DATA_PACKET_DTYPE)
    _fill_blocks(records["blocks"], azimuth, return_mode, (strongest, refl), (last, last_refl))
    offset_us = np.arange(packets) * (per_packet * SEQUENCE_US)
    time_s = (start_time_s + offset_us * 1e-6).astype(np.float64)
    stamp_us = round(start_time_s * 1e6) + np.rint(offset_us).astype(np.int64)  # integers: no drift
    records["timestamp_us"] = (stamp_us % HOUR_US).astype(np.uint32)
    records["return_mode"] = return_mode
    records["product_id"] = product_id
    return EncodedPackets(records.view(np.uint8).reshape(packets, -1), time_s)


def _fill_blocks(blocks: NDArray[np.void], azimuth: NDArray[np.int64], return_mode: ReturnMode,
                 strongest: tuple[NDArray[np.uint16], NDArray[np.integer]],
                 last: tuple[NDArray[np.uint16], NDArray[np.integer]]) -> None:
    """The data blocks of the packets: (P, blocks per mode, 2 firings, 16 lasers) -> channels 0-15 and 16-31 of a
    block; DUAL alternates the last and the strongest returns block by block."""
    packets = len(blocks)
    total = len(azimuth)
    blocks["flag"] = BLOCK_FLAG
    if return_mode is ReturnMode.DUAL:
        shape = (packets, 6, 2 * LASERS)
        for parity, (dist, ref) in enumerate([last, strongest]):
            blocks["azimuth"][:, parity::2] = azimuth.reshape(packets, 6, 2)[:, :, 0]
            blocks["channels"]["distance"][:, parity::2] = _padded(dist, total, 0).reshape(shape)
            blocks["channels"]["reflectivity"][:, parity::2] = _padded(ref, total, 0).reshape(shape)
        return
    source, source_refl = last if return_mode is ReturnMode.LAST else strongest
    shape = (packets, 12, 2 * LASERS)
    blocks["azimuth"] = azimuth.reshape(packets, 12, 2)[:, :, 0]
    blocks["channels"]["distance"] = _padded(source, total, 0).reshape(shape)
    blocks["channels"]["reflectivity"] = _padded(source_refl, total, 0).reshape(shape)


def gprmc_sentence(utc_s: float) -> str:
    """A valid ('A') $GPRMC sentence for the UTC time ``utc_s`` at a fixed position, with its checksum."""
    day, centis = divmod(round(float(utc_s) * 100), 8_640_000)
    hours, centis = divmod(centis, 360_000)
    minutes, centis = divmod(centis, 6000)
    date = datetime.fromtimestamp(day * 86400, UTC)
    body = (
        f"GPRMC,{hours:02d}{minutes:02d}{centis // 100:02d}.{centis % 100:02d},A,4807.038,N,01131.000,E,"
        f"000.0,000.0,{date:%d%m%y},,,A"
    )
    return f"${body}*{reduce(lambda a, c: a ^ ord(c), body, 0):02X}"


def encode_position_packet(timestamp_us: int, pps: PpsStatus, nmea: str = "") -> bytes:
    """A 512-byte position packet with the device timestamp, PPS status and (NUL-terminated) sentence."""
    text = nmea.encode("ascii")
    if len(text) >= POSITION_PACKET_SIZE - POSITION_NMEA_OFFSET:
        raise EncodeError(f"encoder: NMEA sentence of {len(text)} bytes does not fit a position packet")
    packet = bytearray(POSITION_PACKET_SIZE)
    struct.pack_into("<I", packet, POSITION_TIMESTAMP_OFFSET, int(timestamp_us) % HOUR_US)
    packet[POSITION_PPS_OFFSET] = int(pps)
    packet[POSITION_NMEA_OFFSET : POSITION_NMEA_OFFSET + len(text)] = text
    return bytes(packet)
