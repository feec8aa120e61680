"""Sweep assembly on encoded synthetic streams: cuts, losses, reordering, clock rollover, GPS time."""

from __future__ import annotations

import numpy as np
import pytest
from vlp16_helpers import FIRING_S, assemble, batch_of, synthetic_firings

from drivers.vlp16 import (
    DatagramBatch,
    EncodedPackets,
    PacketFault,
    PositionDatagram,
    PpsStatus,
    ReturnMode,
    SweepAssembler,
    TimeSource,
    Vlp16Config,
    encode_data_packets,
    encode_position_packet,
    gprmc_sentence,
)


def stream(
    turns: float,
    rpm: float = 600.0,
    mode: ReturnMode = ReturnMode.STRONGEST,
    start_deg: float = 30.0,
    start_time_s: float = 1000.0,
    seed: int = 0,
) -> EncodedPackets:
    firings = int(turns * 60.0 / rpm / FIRING_S)
    f = synthetic_firings(firings, rpm=rpm, start_deg=start_deg, start_time_s=start_time_s, seed=seed)
    return encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, start_time_s, mode)


def batches(
    packets: EncodedPackets, order: np.ndarray | None = None, size: int = 16, host_offset_s: float = 0.0
) -> list[DatagramBatch]:
    """Feed order ``order`` (default: as sent) in batches of ``size``; host time = send time + offset."""
    order = np.arange(len(packets.payloads)) if order is None else order
    return [
        batch_of(packets.payloads[chunk], packets.time_s[chunk] + host_offset_s, first_index=int(start))
        for start, chunk in ((s, order[s : s + size]) for s in range(0, len(order), size))
    ]


def test_sweeps_start_at_the_cut_azimuth_and_cover_a_turn() -> None:
    packets = stream(3.9, start_deg=200.0)  # 250 deg to the cut, three turns, 154 deg
    sweeps, assembler = assemble(batches(packets), Vlp16Config(cut_azimuth_deg=90.0))
    assert [s.complete for s in sweeps] == [False, True, True, True, False]
    for sweep in sweeps[1:-1]:
        from_cut = (sweep.points["azimuth"] - 90.0) % 360.0
        block_step = 2 * 360.0 * 10 * FIRING_S  # two firings at 600 rpm
        assert from_cut.min() < block_step and from_cut.max() > 360.0 - 2 * block_step
        assert sweep.end.device - sweep.start.device == pytest.approx(0.1, abs=2 * block_step / 3600)
        assert sweep.rpm == pytest.approx(600.0, rel=2e-3)
        assert sweep.missing_packets == 0
    assert assembler.stats().data_packets == len(packets.payloads)


@pytest.mark.parametrize("rpm", [300.0, 1200.0])
def test_rpm_estimate(rpm: float) -> None:
    sweeps, _ = assemble(batches(stream(2.5, rpm=rpm)))
    assert all(s.rpm == pytest.approx(rpm, rel=2e-3) for s in sweeps)


@pytest.mark.parametrize("mode", [ReturnMode.STRONGEST, ReturnMode.DUAL])
def test_dropped_packets_are_reported_per_sweep(mode: ReturnMode) -> None:
    packets = stream(3.2, mode=mode)
    clean, _ = assemble(batches(packets))
    dropped = np.array([5, 6, 7, 90, 150])
    sweeps, assembler = assemble(batches(packets, np.setdiff1d(np.arange(len(packets.payloads)), dropped)))
    assert len(sweeps) == len(clean)
    assert sum(s.missing_packets for s in sweeps) == len(dropped) == assembler.stats().missing_packets
    for ours, full in zip(sweeps, clean, strict=True):
        first_packet = round((full.start.device - clean[0].start.device) / mode.packet_period_us / 1e-6)
        last_packet = first_packet + full.packet_count
        lost_here = np.count_nonzero((dropped > first_packet) & (dropped < last_packet))
        assert ours.missing_packets >= lost_here
        assert len(ours.points) < len(full.points) or lost_here == 0


def test_reordered_and_duplicated_packets_give_the_same_sweeps() -> None:
    packets = stream(2.7)
    clean, _ = assemble(batches(packets))
    rng = np.random.default_rng(1)
    order = np.arange(len(packets.payloads))
    for start in range(0, len(order) - 4, 4):  # shuffle within groups of 4 (inside the reorder window)
        order[start : start + 4] = rng.permutation(order[start : start + 4])
    order = np.insert(order, [20, 100], [19, 99])  # two duplicates
    sweeps, assembler = assemble(batches(packets, order, size=7))
    assert len(sweeps) == len(clean)
    for ours, full in zip(sweeps, clean, strict=True):
        assert np.array_equal(ours.points, full.points) and ours.missing_packets == 0
    assert assembler.stats().faults == {PacketFault.DUPLICATE: 2}


def test_a_packet_later_than_its_sweep_is_counted_late_and_missing() -> None:
    packets = stream(2.5)
    order = np.arange(len(packets.payloads))
    order = np.append(np.delete(order, 10), 10)  # packet 10 arrives at the very end
    sweeps, assembler = assemble(batches(packets, order), Vlp16Config(reorder_window=2))
    stats = assembler.stats()
    assert stats.faults == {PacketFault.LATE: 1}
    assert stats.first_fault[PacketFault.LATE] == len(order) - 1
    assert stats.missing_packets == 1 == sweeps[0].missing_packets


def test_a_gap_longer_than_a_turn_ends_the_sweep() -> None:
    packets = stream(3.0, start_deg=100.0)  # 4.78 deg per packet
    # Packets 0-39 reach 291 deg; 80 lost packets are 382 deg, so packet 120 is at 313 deg: the azimuths
    # on either side of the gap do not show that the cut (0 deg) was passed.
    keep = np.r_[0:40, 120 : len(packets.payloads)]
    sweeps, _ = assemble(batches(packets, keep))
    assert sum(s.missing_packets for s in sweeps) == 80
    assert sweeps[0].missing_packets == 80 and not sweeps[0].complete and not sweeps[1].complete
    assert ((sweeps[1].points["azimuth"] - 313.0) % 360.0).max() < 48.0  # 313 deg to the cut, not a turn
    assert all(s.end.device - s.start.device < 0.1 + 1e-3 for s in sweeps)


def test_an_azimuth_stepping_back_is_not_a_crossing() -> None:
    packets = stream(2.5, start_deg=100.0)
    clean, _ = assemble(batches(packets))
    shaky = packets.payloads.copy()
    azimuth = shaky[40, 302:304].view("<u2")  # block 3 of packet 40 reads 0.05 deg behind block 2
    azimuth[0] = shaky[40, 202:204].view("<u2")[0] - 5
    sweeps, _ = assemble(batches(packets._replace(payloads=shaky)))
    assert [len(s.points) for s in sweeps] == [len(s.points) for s in clean]


def test_device_clock_rollover_at_the_top_of_the_hour() -> None:
    start = 7200.0 - 0.15  # the device counts microseconds past the hour: it wraps 0.15 s in
    packets = stream(3.0, start_time_s=start)
    stamps = packets.payloads[:, 1200:1204].copy().view("<u4").ravel()
    assert stamps[0] > 3_599_800_000 and stamps[-1] < 200_000  # the stream really wraps
    sweeps, assembler = assemble(batches(packets, host_offset_s=0.004))
    assert assembler.stats().missing_packets == 0 and len(sweeps) == 4
    starts = np.array([s.start.device for s in sweeps])
    assert np.all(np.diff(starts) > 0.09)
    assert starts[0] == pytest.approx(start, abs=1e-6)  # hour resolved against the host clock
    for sweep in sweeps:
        assert np.all(np.diff(sweep.points["time"]) >= -1e-9) and sweep.points["time"].max() < 0.1 + 1e-4


def test_gps_time_when_pps_is_locked_else_host_time_with_offset() -> None:
    utc0 = 1_700_000_000.0  # the device clock is disciplined: its stamps are UTC microseconds past the hour
    packets = stream(2.5, start_time_s=utc0)
    host_ahead = 2.75  # host clock error plus network latency
    position = encode_position_packet(
        round((utc0 + 0.2) * 1e6) % 3_600_000_000, PpsStatus.LOCKED, gprmc_sentence(np.floor(utc0 + 0.2))
    )
    data = batches(packets, host_offset_s=host_ahead)
    locked = [DatagramBatch(positions=(PositionDatagram(position, utc0 + 0.2 + host_ahead, 999),)), *data]
    sweeps, assembler = assemble(locked)
    assert all(s.time_source is TimeSource.GPS and s.pps is PpsStatus.LOCKED for s in sweeps)
    assert sweeps[0].start.device == pytest.approx(utc0, abs=1e-6)
    assert sweeps[0].time_s == sweeps[0].start.device
    assert sweeps[0].clock_offset_s == pytest.approx(host_ahead, abs=1e-6)
    assert assembler.stats().position_packets == 1

    unlocked = encode_position_packet(0, PpsStatus.SYNCHRONISING, "")
    host_sweeps, _ = assemble([DatagramBatch(positions=(PositionDatagram(unlocked, utc0, 0),)), *data])
    assert all(s.time_source is TimeSource.HOST for s in host_sweeps)
    assert host_sweeps[0].time_s == pytest.approx(utc0 + host_ahead, abs=1e-6)
    assert host_sweeps[0].start.host == pytest.approx(utc0 + host_ahead, abs=1e-6)


def test_invalid_pps_byte_is_counted() -> None:
    bad = bytearray(encode_position_packet(0, PpsStatus.LOCKED, ""))
    bad[202] = 9
    _, assembler = assemble([DatagramBatch(positions=(PositionDatagram(bytes(bad), 0.0, 3),))])
    assert assembler.stats().faults == {PacketFault.POSITION: 1}
    assert assembler.stats().first_fault == {PacketFault.POSITION: 3}


def test_a_forward_clock_step_is_not_lost_packets() -> None:
    packets = stream(3.2)
    stepped = packets.payloads.copy()
    stamps = stepped[:, 1200:1204].view("<u4")
    stamps[100:] = (stamps[100:].astype(np.int64) + 10_000_000) % 3_600_000_000  # device clock +10 s at packet 100
    dropped = np.array([30, 31, 170])  # real losses, before and after the step
    keep = np.setdiff1d(np.arange(len(stepped)), dropped)
    sweeps, assembler = assemble(batches(packets._replace(payloads=stepped), keep))
    # The host received packets 99 and 100 1.3 ms apart: the 10 s are the clock's, not 7,535 lost packets.
    assert assembler.stats().missing_packets == len(dropped) == sum(s.missing_packets for s in sweeps)


def test_a_head_that_does_not_turn_gives_incomplete_sweeps_while_it_streams() -> None:
    f = synthetic_firings(int(1.6 / FIRING_S))  # 1.6 s of firings, all at one azimuth: the motor stopped
    packets = encode_data_packets(f.ranges_m, f.reflectivity, np.full(len(f.time_s), 123.0), 1000.0)
    assembler = SweepAssembler()
    streamed = [s for batch in batches(packets) for s in assembler.feed(batch)]
    # Every 0.5 s of packets goes out (memory stays bounded) as an incomplete sweep of a head at 0 rpm.
    assert len(streamed) == 3
    assert all(not s.complete and s.rpm == 0.0 and s.packet_count > 370 for s in streamed)
    rest = assembler.flush()
    assert sum(s.packet_count for s in streamed + rest) == len(packets.payloads)
    assert assembler.stats().missing_packets == 0
    assert np.allclose(np.concatenate([s.points["azimuth"] for s in streamed]), 123.0)
