"""The device clock against the host clock: steps back and forward seen from the packets' receive times,
each recorded and the offset measured afresh; receive delays, stalls and reordering are not steps."""

from __future__ import annotations

import numpy as np
import pytest
from vlp16_helpers import FIRING_S, LEGACY_PCAP, assemble, batch_of, synthetic_firings

from drivers.vlp16 import (
    DatagramBatch,
    EncodedPackets,
    PacketFault,
    PositionDatagram,
    PpsStatus,
    StepKind,
    Sweep,
    TimeSource,
    Vlp16Config,
    encode_data_packets,
    encode_position_packet,
    gprmc_sentence,
    read_sweeps,
)

HOUR_US = 3_600_000_000
START_S = 1_700_000_000.0  # the host clock when the sensor's first packet leaves


def stream(turns: float, start_time_s: float = START_S) -> EncodedPackets:
    firings = int(turns * 0.1 / FIRING_S)
    f = synthetic_firings(firings, start_deg=30.0, start_time_s=start_time_s)
    return encode_data_packets(f.ranges_m, f.reflectivity, f.azimuth_deg, start_time_s)


def stepped(packets: EncodedPackets, at: int, step_s: float) -> EncodedPackets:
    """The same packets with the device clock stepped by ``step_s`` from packet ``at`` on (send times kept)."""
    payloads = packets.payloads.copy()
    stamps = payloads[:, 1200:1204].view("<u4")
    stamps[at:] = (stamps[at:].astype(np.int64) + round(step_s * 1e6)) % HOUR_US
    return packets._replace(payloads=payloads)


def received(packets: EncodedPackets, order: np.ndarray | None = None, delay_s: np.ndarray | None = None,
             size: int = 16) -> list[DatagramBatch]:
    """Batches in arrival ``order``; each packet received at its send time + 0.3 ms + ``delay_s``."""
    order = np.arange(len(packets.payloads)) if order is None else order
    host = packets.time_s + 3e-4 + (0.0 if delay_s is None else delay_s)
    return [batch_of(packets.payloads[chunk], host[chunk], first_index=int(start))
            for start, chunk in ((s, order[s : s + size]) for s in range(0, len(order), size))]


def host_start(sweep: Sweep) -> float:
    """The sweep's start on the host clock as capture places it: device time + the segment's offset."""
    return sweep.start.device + sweep.clock_offset_s


def assert_on_the_host_clock(sweeps: list[Sweep]) -> None:
    """Every sweep sits where its packets were received, whatever the device clock did: its first firing
    within the packet that holds it (1.3 ms) of that packet's receipt."""
    for sweep in sweeps:
        assert -1e-6 <= host_start(sweep) - sweep.start.host < 1.3e-3  # (UNIX seconds hold 0.2 us)
        assert -1e-6 <= sweep.receive_offset_s - sweep.clock_offset_s < 1e-3


@pytest.mark.parametrize("step_s", [-3.0, -0.5, 2.0, 10.0])
def test_a_clock_step_is_recorded_and_the_offset_measured_again(step_s: float) -> None:
    packets = stepped(stream(8.0), 400, step_s)
    sweeps, assembler = assemble(received(packets))
    stats = assembler.stats()
    assert len(stats.clock_steps) == 1
    step = stats.clock_steps[0]
    assert step.step_s == pytest.approx(step_s, abs=1e-3)
    assert step.kind is (StepKind.BACK if step_s < 0 else StepKind.FORWARD)
    assert step.host_s == pytest.approx(packets.time_s[400] + 3e-4, abs=1e-6)
    assert stats.faults == {} and stats.missing_packets == 0  # nothing late, nothing lost
    assert stats.data_packets == len(packets.payloads)
    assert_on_the_host_clock(sweeps)
    # The sweep open at the step ends there and the next begins with it, both incomplete: none mixes two clocks.
    assert not any(s.start.host < step.host_s <= s.end.host for s in sweeps)
    ending = max((s for s in sweeps if s.end.host < step.host_s), key=lambda s: s.end.host)
    beginning = next(s for s in sweeps if s.start.host == step.host_s)
    assert not ending.complete and not beginning.complete
    assert sum(s.complete for s in sweeps) >= 3
    assert np.all(np.diff([host_start(s) for s in sweeps]) > 0)


def test_a_stream_whose_first_packets_came_late_has_no_step() -> None:
    """The receiver was busy as the stream began: its first 150 packets were read 0.2 s late, in one burst,
    so their delays fall packet by packet to nothing, never by a step."""
    packets = stream(6.0)
    delay = np.maximum(0.2 - 1.3e-3 * np.arange(len(packets.payloads)), 0.0)
    sweeps, assembler = assemble(received(packets, delay_s=delay, size=64))
    assert assembler.stats().clock_steps == ()
    assert assembler.stats().clock_offset_s == pytest.approx(3e-4, abs=1e-4)


def test_without_steps_the_offset_is_the_least_delayed_packet() -> None:
    packets = stream(4.0)
    delay = np.random.default_rng(0).exponential(2e-3, len(packets.payloads))  # a busy network
    delay[150:160] += 0.4  # and a receiver that stalled 0.4 s, then read its backlog at once
    delay[150:160] -= np.arange(10) * 1.3e-3
    sweeps, assembler = assemble(received(packets, delay_s=delay))
    assert assembler.stats().clock_steps == ()
    offsets = {s.clock_offset_s for s in sweeps}
    assert max(offsets) - 3e-4 < 1e-3  # the smallest delays, not the stall
    stalled = [s for s in sweeps if s.receive_offset_s - s.clock_offset_s > 0.01]
    assert len(stalled) <= 1  # only the stalled turn shows its delay, and only in receive_offset_s


def test_a_sender_falling_behind_its_stamps_is_not_a_step() -> None:
    """A sensor (or a simulator) that sends later and later after its own stamps, 0.2 s more every second
    for 2 s, then catches up: the delays rise for longer than SETTLE_S, but never steadily."""
    packets = stream(50.0)
    since = packets.time_s - packets.time_s[0]
    delay = np.where(since < 2.0, 0.2 * since, np.maximum(0.4 - 0.5 * (since - 2.0), 0.0))
    _, assembler = assemble(received(packets, delay_s=delay))
    assert assembler.stats().clock_steps == ()


def test_packets_reordered_across_a_step_are_late_not_more_steps() -> None:
    packets = stepped(stream(7.0), 400, -3.0)
    order = np.arange(len(packets.payloads))
    order[[398, 399, 400, 401, 402]] = [400, 398, 401, 399, 402]  # two old-clock packets after new-clock ones
    sweeps, assembler = assemble(received(packets, order))
    stats = assembler.stats()
    assert [round(s.step_s, 2) for s in stats.clock_steps] == [-3.0]
    assert stats.faults == {PacketFault.LATE: 2}
    assert_on_the_host_clock(sweeps)


def test_a_step_back_inside_a_gap_is_found_once_the_offsets_stay_raised() -> None:
    packets = stepped(stream(60.0), 1500, -0.5)  # 6 s of stream, the step 2 s in
    # 0.8 s lost around it: the device time still runs forward across the gap, no packet pair shows the step
    keep = np.r_[0:1480, 2100 : len(packets.payloads)]
    sweeps, assembler = assemble(received(packets, keep))
    steps = assembler.stats().clock_steps
    assert len(steps) == 1 and steps[0].kind is StepKind.BACK_SETTLED
    assert steps[0].step_s == pytest.approx(-0.5, abs=1e-3)
    assert steps[0].host_s == pytest.approx(packets.time_s[2100] + 3e-4, abs=1e-6)  # the run began there
    settled = [s for s in sweeps if s.start.host > steps[0].host_s + 1.1]
    assert len(settled) > 10
    assert_on_the_host_clock(settled)
    # Between the gap and the detection, sweeps carry the old offset, and their own packets say so.
    before = [s for s in sweeps if steps[0].host_s < s.start.host < steps[0].host_s + 0.9]
    assert before and all(s.receive_offset_s - s.clock_offset_s == pytest.approx(0.5, abs=2e-3) for s in before)


def test_a_pps_lock_that_steps_the_clock_is_a_step_on_gps_time() -> None:
    """A free-running device clock 2 s behind UTC locks to PPS: its stamps jump 2 s forward and position
    packets say locked with the $GPRMC time; sweeps then run on GPS time at the new offset."""
    packets = stream(5.0)
    behind = stepped(packets, 0, -2.0)
    locked = stepped(behind, 300, 2.0)
    lock_s = packets.time_s[300]
    position = encode_position_packet(round(lock_s * 1e6) % HOUR_US, PpsStatus.LOCKED,
                                      gprmc_sentence(np.floor(lock_s)))
    batches = received(locked)
    at = next(k for k, b in enumerate(batches) if b.data_host_s[0] > lock_s)
    batches.insert(at, DatagramBatch(positions=(PositionDatagram(position, lock_s + 3e-4, 99_999),)))
    sweeps, assembler = assemble(batches)
    steps = assembler.stats().clock_steps
    assert [round(s.step_s, 3) for s in steps] == [2.0]
    assert_on_the_host_clock(sweeps)
    after = [s for s in sweeps if s.start.host > lock_s + 0.01]
    assert after and all(s.time_source is TimeSource.GPS for s in after)
    assert all(s.start.device == pytest.approx(s.start.host - 3e-4, abs=1e-3) for s in after)  # UTC again


def test_coverage_is_the_fraction_of_a_turn_received() -> None:
    packets = stream(4.0)
    clean, _ = assemble(received(packets))
    assert all(0.998 < s.coverage < 1.002 for s in clean if s.complete)
    lost = np.arange(100, 175, 4)  # 19 packets (of a 75-packet turn) over two sweeps
    lossy, _ = assemble(received(packets, np.setdiff1d(np.arange(len(packets.payloads)), lost)))
    hit = [s for s in lossy if s.complete and s.missing_packets]
    assert len(hit) == 2 and sum(s.missing_packets for s in hit) == len(lost)
    assert sum(1.0 - s.coverage for s in hit) == pytest.approx(len(lost) / 75.3, abs=0.01)


def test_a_real_capture_has_no_steps_whole_turns_and_millisecond_receive_lags() -> None:
    """VeloView's capture (1200 rpm, pcap record times as the host clock): the clock never steps, each
    sweep's own packets agree with the stream's offset within a millisecond, and whole turns cover 1.0."""
    sweeps, stats = read_sweeps(LEGACY_PCAP, Vlp16Config(product_ids=None))
    assert stats.clock_steps == ()
    assert all(0.0 <= s.receive_offset_s - s.clock_offset_s < 1e-3 for s in sweeps)
    assert all(0.997 < s.coverage < 1.003 for s in sweeps if s.complete)
