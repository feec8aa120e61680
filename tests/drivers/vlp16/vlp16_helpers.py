"""Shared test helpers: paths to the real captures, synthetic firings, and velodyne-decoder as the peer."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import dpkt
import numpy as np

from drivers.vlp16 import DatagramBatch, Sweep, SweepAssembler, Vlp16Config
from tests.testdata import LEGACY_PCAP, SMALL_PCAP

__all__ = ["LEGACY_PCAP", "SMALL_PCAP"]  # re-exported for the test modules

FIRING_S = 55.296e-6
# The VLP-16 manual's geometry, written out here rather than taken from the driver: nominal elevations of lasers
# 0..15 (deg) and each laser's origin 41.91 mm * tan(-elevation) above the sensor origin (m).
ELEVATION_DEG = np.array([-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15], dtype=np.float64)
MANUAL_OFFSET_M = 0.04191 * np.tan(np.radians(-ELEVATION_DEG))


class Firings(NamedTuple):
    """Synthetic sensor firings: ranges_m (F,16) m (0 = no return), reflectivity (F,16) uint8,
    azimuth_deg (F,) at a constant spin, time_s (F,) of each firing."""

    ranges_m: np.ndarray
    reflectivity: np.ndarray
    azimuth_deg: np.ndarray
    time_s: np.ndarray


def synthetic_firings(
    count: int,
    rpm: float = 600.0,
    start_deg: float = 0.0,
    start_time_s: float = 1000.0,
    seed: int = 0,
    no_return_fraction: float = 0.05,
) -> Firings:
    """``count`` firings of a sensor spinning at ``rpm`` in a room-like scene (1-60 m), some no-return."""
    rng = np.random.default_rng(seed)
    time_s = start_time_s + np.arange(count) * FIRING_S
    azimuth_deg = (start_deg + rpm / 60.0 * 360.0 * (time_s - start_time_s)) % 360.0
    walls = 8.0 + 6.0 * np.sin(np.radians(3 * azimuth_deg))[:, None] + np.arange(16)[None, :] * 0.5
    ranges = (
        walls
        + rng.uniform(-0.5, 0.5, (count, 16))
        + rng.uniform(0, 40, (count, 1)) * (rng.random((count, 1)) < 0.1)
    )
    ranges[rng.random((count, 16)) < no_return_fraction] = 0.0
    reflectivity = rng.integers(1, 256, (count, 16)).astype(np.uint8)
    return Firings(ranges, reflectivity, azimuth_deg, time_s)


def batch_of(payloads: np.ndarray, host_s: np.ndarray, first_index: int = 0) -> DatagramBatch:
    """A DatagramBatch of (K,1206) data payloads with host times, indexed from ``first_index``."""
    return DatagramBatch(
        np.ascontiguousarray(payloads),
        np.asarray(host_s, dtype=np.float64),
        first_index + np.arange(len(payloads), dtype=np.int64),
    )


def assemble(
    batches: list[DatagramBatch], config: Vlp16Config | None = None
) -> tuple[list[Sweep], SweepAssembler]:
    """Feed batches through a new assembler and flush it."""
    assembler = SweepAssembler(config)
    sweeps: list[Sweep] = []
    for batch in batches:
        sweeps += assembler.feed(batch)
    return sweeps + assembler.flush(), assembler


def data_payloads(path: Path, product_id: int | None = None) -> Iterator[tuple[float, bytes]]:
    """(pcap time, 1206-byte payload) of the data packets of a capture, optionally with byte 1205 replaced."""
    with path.open("rb") as fh:
        for stamp, frame in dpkt.pcap.Reader(fh):
            udp = dpkt.ethernet.Ethernet(frame).data.data
            if udp.dport == 2368 and len(udp.data) == 1206:
                payload = bytes(udp.data)
                if product_id is not None:
                    payload = payload[:-1] + bytes([product_id])
                yield float(stamp), payload
