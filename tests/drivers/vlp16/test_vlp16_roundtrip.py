"""Encoder -> decoder round trips on synthetic firings, in strongest, last and dual-return modes.

Expected points come from the firings themselves (range, the firing's true azimuth, the laser's elevation
and vertical offset from the VLP-16 manual, the decoder's default geometry), not from the decoder: ranges
survive to the 2 mm quantum, azimuths to the 0.01 deg quantum plus the in-block interpolation, times to the
microsecond rounding of the packet stamp.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import velodyne_decoder as vd
from vlp16_helpers import ELEVATION_DEG, FIRING_S, MANUAL_OFFSET_M, synthetic_firings

from drivers.vlp16 import (
    POINT_DTYPE,
    PcapReplay,
    ReturnMode,
    ReturnType,
    decode_packets,
    encode_data_packets,
    write_pcap,
)

RING_OF_LASER = np.argsort(np.argsort(ELEVATION_DEG, kind="stable"), kind="stable")


def expected_points(
    ranges: np.ndarray,
    reflectivity: np.ndarray,
    azimuth_deg: np.ndarray,
    time_s: np.ndarray,
    rpm: float = 600.0,
) -> np.ndarray:
    """The points a perfect sensor reports for (F,16) returns, in firing-then-laser order, zeros dropped."""
    firing, laser = np.nonzero(ranges > 0)
    delay_s = laser * 2.304e-6
    azimuth = azimuth_deg[firing] + rpm / 60.0 * 360.0 * delay_s  # the head turns while the lasers fire
    w = np.radians(ELEVATION_DEG[laser])
    r = ranges[firing, laser]
    a = np.radians(azimuth)
    out = np.empty(len(r), POINT_DTYPE)
    out["x"], out["y"] = r * np.cos(w) * np.cos(a), -r * np.cos(w) * np.sin(a)
    out["z"] = r * np.sin(w) + MANUAL_OFFSET_M[laser]  # the beam starts at the laser, not the sensor origin
    out["intensity"] = reflectivity[firing, laser]
    out["time"] = time_s[firing] + delay_s
    out["ring"] = RING_OF_LASER[laser]
    out["azimuth"] = azimuth % 360.0
    return out


def by_time_and_ring(points: np.ndarray) -> np.ndarray:
    return points[np.lexsort((points["ring"], points["time"]))]


def assert_close(decoded: np.ndarray, expected: np.ndarray, start_time_s: float) -> None:
    assert len(decoded) == len(expected)
    r_dec = np.sqrt(decoded["x"] ** 2.0 + decoded["y"] ** 2 + decoded["z"] ** 2)
    r_exp = np.sqrt(expected["x"] ** 2.0 + expected["y"] ** 2 + expected["z"] ** 2)
    assert np.abs(r_dec - r_exp).max() <= 0.001 + 1e-5  # ranges to the 2 mm quantum (half of it + float32)
    # Azimuth error: block azimuth quantum 0.005 + output quantum 0.005 + the packet's rate measured from two
    # quantised azimuths 10 (dual) firing sequences apart, applied up to 1.625 sequences into a block: 0.0016.
    az_bound = 0.0117
    az_error = (decoded["azimuth"] - expected["azimuth"] + 180.0) % 360.0 - 180.0
    assert np.abs(az_error).max() <= az_bound
    position_error = np.linalg.norm(
        np.stack([decoded[c] - expected[c] for c in "xyz"], axis=1).astype(np.float64), axis=1
    )
    assert np.all(position_error <= 0.001 + r_exp * np.radians(az_bound) + 1e-5)
    # Decoded times are seconds past the hour of the device clock, stamps rounded to 1 us.
    assert np.abs(decoded["time"] - (expected["time"] - start_time_s + start_time_s % 3600)).max() <= 1e-6
    assert np.array_equal(decoded["ring"], expected["ring"])
    assert np.array_equal(decoded["intensity"], expected["intensity"])


@pytest.mark.parametrize("mode", [ReturnMode.STRONGEST, ReturnMode.LAST])
def test_single_return_round_trip(mode: ReturnMode) -> None:
    f = synthetic_firings(1800, rpm=600.0, start_deg=123.4, start_time_s=1234.5)
    packets = encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 1234.5, mode)
    assert packets.payloads.shape == (75, 1206)
    decoded = decode_packets(packets.payloads).points
    assert_close(decoded, expected_points(f.ranges_m, f.reflectivity, f.azimuth_deg, f.time_s), 1234.5)
    expected_type = ReturnType.STRONGEST if mode is ReturnMode.STRONGEST else ReturnType.LAST
    assert np.all(decoded["return_type"] == expected_type)


def test_dual_return_round_trip_keeps_both_returns_and_merges_repeats() -> None:
    f = synthetic_firings(900, rpm=600.0, start_deg=10.0)
    last = f.ranges_m.copy()
    farther = (np.arange(16) % 3 == 0)[None, :] & (f.ranges_m > 0)  # a second, farther echo on some lasers
    last[farther] += 5.0
    packets = encode_data_packets(
        f.ranges_m, f.reflectivity, f.azimuth_deg, 1000.0, ReturnMode.DUAL, last_ranges_m=last
    )
    assert packets.payloads.shape == (75, 1206)  # 12 firings per packet in dual mode
    decoded = decode_packets(packets.payloads).points
    expected_by_kind = {
        ReturnType.LAST: np.where(farther, last, 0.0),
        ReturnType.STRONGEST: np.where(farther, f.ranges_m, 0.0),
        ReturnType.BOTH: np.where(farther, 0.0, f.ranges_m),  # one echo: both blocks repeat it, kept once
    }
    assert len(decoded) == sum(np.count_nonzero(r) for r in expected_by_kind.values())
    for kind, ranges in expected_by_kind.items():
        part = by_time_and_ring(decoded[decoded["return_type"] == kind])
        expected = by_time_and_ring(expected_points(ranges, f.reflectivity, f.azimuth_deg, f.time_s))
        assert_close(part, expected, 1000.0)


@pytest.mark.parametrize("mode", list(ReturnMode))
def test_encoded_packets_decode_the_same_in_the_peer(mode: ReturnMode) -> None:
    """The peer reads our encoder's packets as we do, both with their default geometry (the manual's): the encoder
    writes the real format."""
    f = synthetic_firings(480, start_deg=359.0)
    packets = encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 2000.0, mode)
    decoder = vd.StreamDecoder(vd.Config(model=vd.Model.VLP16))
    scans = [
        decoder.decode(float(t), p.tobytes(), True)
        for t, p in zip(packets.time_s, packets.payloads, strict=True)
    ]
    scans.append(decoder.finish(True))
    peer = np.concatenate([points for _, points in filter(None, scans)])
    mine = decode_packets(packets.payloads).points
    assert len(mine) == len(peer) > 0
    for axis in "xyz":
        assert np.abs(mine[axis] - peer[axis]).max() < 1e-4
    assert np.array_equal(mine["return_type"], peer["return_type"])


def test_encoder_pads_a_partial_packet_with_no_returns() -> None:
    f = synthetic_firings(30, no_return_fraction=0.0)
    packets = encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 0.0)
    assert packets.payloads.shape == (2, 1206)
    assert len(decode_packets(packets.payloads).points) == 30 * 16
    assert packets.time_s[1] - packets.time_s[0] == pytest.approx(24 * FIRING_S)


def test_pcap_writer_round_trip_through_file_replay(tmp_path: Path) -> None:
    f = synthetic_firings(800 + 1800 * 2 + 500, rpm=600.0, start_deg=200.0, start_time_s=1_700_000_000.0)
    packets = encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 1_700_000_000.0)
    path = tmp_path / "sim.pcap"
    assert write_pcap(
        path, [(t, 2368, p.tobytes()) for t, p in zip(packets.time_s, packets.payloads, strict=True)]
    ) == len(packets.payloads)
    replay = PcapReplay(path)
    sweeps = list(replay)
    assert replay.stats.data_packets == len(packets.payloads) and replay.stats.bad_packets == 0
    # Start at 200 deg: a piece 200..360, two whole turns, then the rest. At 600 rpm a turn takes
    # 0.1 s / 55.296 us = 1808.4 firings; a sweep holds whole blocks (2 firings) from cut to cut.
    assert [s.complete for s in sweeps] == [False, True, True, False]
    points = np.concatenate([s.points for s in sweeps])
    expected = expected_points(f.ranges_m, f.reflectivity, f.azimuth_deg, f.time_s)
    assert len(points) == len(expected)
    for sweep in sweeps[1:3]:
        assert sweep.rpm == pytest.approx(600.0, rel=1e-3)
        since_start = sweep.start.device + sweep.points["time"] - 1_700_000_000.0
        firings = len(np.unique(np.floor(since_start / FIRING_S + 0.1)))
        assert abs(firings - 0.1 / FIRING_S) <= 2


def test_a_single_dual_packet_with_one_echo_per_laser_gives_both_returns_once() -> None:
    f = synthetic_firings(12, no_return_fraction=0.0)
    packets = encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, 0.0, ReturnMode.DUAL)
    points = decode_packets(packets.payloads).points
    assert len(points) == 12 * 16 and np.all(points["return_type"] == ReturnType.BOTH)
