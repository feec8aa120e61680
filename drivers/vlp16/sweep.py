"""Sweep assembly: validated packets in, one record per rotation out (split at a cut azimuth, per block).

A sweep runs from the first block at or past the cut azimuth to the block before the next crossing, as
VeloView splits frames; the packet holding a crossing contributes to both sweeps. Packets are ordered by
device time (within ``reorder_window`` packets of arrival order), duplicates dropped, and a packet that
arrives after its sweep was emitted is counted LATE. Missing packets are gaps in the packet cadence
(1327.104 us, 663.552 us in dual-return mode), except where the device clock stepped forward (the host
received the packets on either side of the gap close together). Packets that cross no cut for longer than
any turn (a head that does not turn) go out as an incomplete sweep every ``STALLED_S``. A step of the device
clock (drivers.vlp16.clock, seen from the receive times) ends the open sweep there, incomplete, and the
stream continues as a new piece, so no sweep mixes two clocks; packets of the old clock reordered past the
step are LATE.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from drivers.vlp16.calibration import LaserCalibration
from drivers.vlp16.clock import ClockStep, DeviceClock, TimePair, TimeSource
from drivers.vlp16.datagrams import DatagramBatch
from drivers.vlp16.decode import decode_packets
from drivers.vlp16.errors import Vlp16Error
from drivers.vlp16.layout import (
    AZIMUTH_UNITS,
    BLOCKS_PER_PACKET,
    DATA_PACKET_SIZE,
    FIRING_US,
    LASERS,
    SEQUENCE_US,
    VLP16_PRODUCT_ID,
    PpsStatus,
    ReturnMode,
    as_packet_records,
)
from drivers.vlp16.position import parse_position_packet
from drivers.vlp16.validate import FaultTally, PacketFault, check_packets

# The VLP-16 turns at 300-1200 rpm (0.05-0.2 s a turn): packets spanning longer without a cut come from a head
# that does not turn. They are emitted rather than held, so memory stays bounded and consumers see them.
STALLED_S = 0.5
# A gap in device time that the host's receive times do not show either, by more than this, is the device
# clock stepping forward, not packets lost: receive delays (network, the receiver's queue) stay far below it.
CLOCK_STEP_S = 0.1


@dataclass(frozen=True)
class Vlp16Config:
    """Decoding and assembly settings.

    ``product_ids``: accepted values of byte 1205 (None = any; pre-2015 firmware writes 0x21).
    ``cut_azimuth_deg``: where sweeps start, deg clockwise from x. ``reorder_window``: packets that must
    follow a crossing before its sweep is emitted (reordering tolerance of a live stream).
    """

    calibration: LaserCalibration = field(default_factory=LaserCalibration)
    product_ids: frozenset[int] | None = frozenset({VLP16_PRODUCT_ID})
    cut_azimuth_deg: float = 0.0
    reorder_window: int = 8

    def __post_init__(self) -> None:
        if not math.isfinite(self.cut_azimuth_deg):
            raise Vlp16Error(f"VLP-16 config: cut azimuth must be a finite angle, got {self.cut_azimuth_deg}")
        if self.reorder_window < 0:
            raise Vlp16Error(f"VLP-16 config: reorder window must be >= 0 packets, got {self.reorder_window}")


@dataclass(frozen=True)
class Sweep:
    """One rotation. ``points`` (N,) POINT_DTYPE with ``time`` s since ``start.device``.

    ``start``/``end``: first and last firing (device s since the epoch; host s of their packets).
    ``complete`` is False for the partial first and last piece of a stream (and the pieces either side of a
    device clock step). ``clock_offset_s`` is host minus device time of the sweep's clock segment (smallest
    seen over the segment, drivers.vlp16.clock); ``receive_offset_s`` the same measured on this sweep's own
    packets alone (>= ``clock_offset_s`` by the least receive delay among them: milliseconds, unless the
    clock estimate is wrong). ``coverage``: the fraction of a turn's firings at this ``rpm`` the sweep holds
    (1.0 for a whole turn, less for each packet lost; a little above 1 by where the cut falls). ``time_s``
    is the sweep start on the best clock available.
    """

    index: int
    points: np.ndarray
    start: TimePair
    end: TimePair
    packet_count: int
    missing_packets: int
    rpm: float
    return_mode: ReturnMode
    complete: bool
    time_source: TimeSource
    clock_offset_s: float
    pps: PpsStatus | None
    receive_offset_s: float = math.inf
    coverage: float = 0.0

    @property
    def time_s(self) -> float:
        """Sweep start: GPS time when PPS is locked, else device time moved onto the host clock."""
        if self.time_source is TimeSource.GPS:
            return self.start.device
        return self.start.device + self.clock_offset_s


@dataclass(frozen=True)
class StreamStats:
    """What a source has seen so far. ``faults``/``first_fault`` by PacketFault (first datagram index)."""

    data_packets: int
    position_packets: int
    sweeps: int
    missing_packets: int
    other_datagrams: int
    overruns: int
    faults: dict[PacketFault, int]
    first_fault: dict[PacketFault, int]
    return_modes: frozenset[ReturnMode]
    product_ids: frozenset[int]
    pps: PpsStatus | None
    time_source: TimeSource
    clock_offset_s: float
    ipv4_fragments: int = 0  # records of a capture that are IPv4 fragments: skipped, not in other_datagrams
    clock_steps: tuple[ClockStep, ...] = ()  # steps of the device clock seen so far (drivers.vlp16.clock)

    @property
    def bad_packets(self) -> int:
        return sum(self.faults.values())

    @property
    def notes(self) -> tuple[str, ...]:
        """Lines for the user about traffic that was skipped without being a bad packet.

        Fragments are counted one by one (a datagram in two fragments counts twice): telling which belong
        together would need the reassembly that is not done.
        """
        if not self.ipv4_fragments:
            return ()
        return (f"{self.ipv4_fragments} IPv4 fragments skipped (fragmented datagrams are not reassembled)",)


@dataclass
class _Pending:
    """Packets not yet emitted, by device time; the open sweep starts at ``start_block`` of packet 0."""

    payloads: NDArray[np.uint8]
    host_s: NDArray[np.float64]
    count_us: NDArray[np.int64]
    index: NDArray[np.int64]
    start_block: int = 0
    started: bool = False  # the open sweep began at a cut (else it is the stream's first piece)

    @classmethod
    def empty(cls) -> _Pending:
        return cls(
            np.empty((0, DATA_PACKET_SIZE), np.uint8),
            np.empty(0),
            np.empty(0, np.int64),
            np.empty(0, np.int64),
        )

    def merged(
        self,
        payloads: NDArray[np.uint8],
        host_s: NDArray[np.float64],
        count_us: NDArray[np.int64],
        index: NDArray[np.int64],
    ) -> _Pending:
        return replace(
            self,
            payloads=np.concatenate([self.payloads, payloads]),
            host_s=np.concatenate([self.host_s, host_s]),
            count_us=np.concatenate([self.count_us, count_us]),
            index=np.concatenate([self.index, index]),
        )

    def take(self, keep: NDArray[np.intp] | slice) -> _Pending:
        return replace(
            self,
            payloads=self.payloads[keep],
            host_s=self.host_s[keep],
            count_us=self.count_us[keep],
            index=self.index[keep],
        )


_SINGLE_BLOCK_US = 2 * np.arange(BLOCKS_PER_PACKET) * SEQUENCE_US
_DUAL_BLOCK_US = 2 * (np.arange(BLOCKS_PER_PACKET) // 2) * SEQUENCE_US


def _block_delay_us(block: int, dual: bool) -> float:
    """Delay of a block's first firing after its packet timestamp, us."""
    return float((_DUAL_BLOCK_US if dual else _SINGLE_BLOCK_US)[block])


def packet_rate(azimuth: NDArray[np.int64], dual: NDArray[np.bool_]) -> NDArray[np.float64]:
    """(P,) rotation rate of each packet from its first and last block azimuth, azimuth units per us."""
    span_us = np.where(dual, 10, 22) * SEQUENCE_US
    return ((azimuth[:, -1] - azimuth[:, 0]) % AZIMUTH_UNITS) / span_us


class SweepAssembler:
    """Feed datagram batches, get sweeps. Not thread-safe: one per stream, used by one thread."""

    def __init__(self, config: Vlp16Config | None = None) -> None:
        self.config = config or Vlp16Config()
        self.clock = DeviceClock()
        self.tally = FaultTally()
        self._pending = _Pending.empty()
        self._floor_us: int | None = None  # device count of the first packet not yet emitted
        self._next_index = 0
        self._counts = {"data": 0, "position": 0, "missing": 0, "other": 0, "fragments": 0}
        self._modes: set[ReturnMode] = set()
        self._products: set[int] = set()
        self._cut_units = round(self.config.cut_azimuth_deg * 100) % AZIMUTH_UNITS
        self._offset_s = math.inf  # host minus device time of the clock segment being assembled

    # -- input ---------------------------------------------------------------------------------------------
    def feed(self, batch: DatagramBatch) -> list[Sweep]:
        """Take one batch (positions first, then data packets); return the sweeps it completes."""
        for fault, count, first in batch.faults:
            self.tally.add(fault, count, first)
        self._counts["other"] += batch.other
        self._counts["fragments"] += batch.fragments
        for position in batch.positions:
            packet = parse_position_packet(position.payload)
            if packet is None:
                self.tally.add(PacketFault.POSITION, 1, position.number)
                continue
            self._counts["position"] += 1
            self.clock.observe_position(packet)
        if len(batch.data) == 0:
            return []
        return self._feed_data(batch.data, batch.data_host_s, batch.data_index)

    def flush(self) -> list[Sweep]:
        """End of stream: emit every pending sweep; the last one, cut short, is incomplete."""
        return self._split(final=True) if len(self._pending.count_us) else []

    def stats(self, overruns: int = 0) -> StreamStats:
        return StreamStats(
            self._counts["data"],
            self._counts["position"],
            self._next_index,
            self._counts["missing"],
            self._counts["other"],
            overruns,
            dict(self.tally.counts),
            dict(self.tally.first_index),
            frozenset(self._modes),
            frozenset(self._products),
            self.clock.pps,
            self.clock.source,
            self.clock.host_offset_s,
            ipv4_fragments=self._counts["fragments"],
            clock_steps=self.clock.steps,
        )

    # -- internals -----------------------------------------------------------------------------------------
    def _valid(self, payloads: NDArray[np.uint8], index: NDArray[np.int64]) -> NDArray[np.bool_]:
        records = as_packet_records(payloads)
        self._products.update(np.unique(records["product_id"]).tolist())
        product_ids: Collection[int] | None = self.config.product_ids
        check = check_packets(records, product_ids)
        self.tally.add_check(check, index)
        modes = np.unique(records["return_mode"][check.valid])
        self._modes.update(ReturnMode(int(m)) for m in modes)
        return check.valid

    def _feed_data(
        self, payloads: NDArray[np.uint8], host_s: NDArray[np.float64], index: NDArray[np.int64]
    ) -> list[Sweep]:
        valid = self._valid(payloads, index)
        if not valid.all():
            payloads, host_s, index = payloads[valid], host_s[valid], index[valid]
        if len(payloads) == 0:
            return []
        count_us = self.clock.unwrap(as_packet_records(payloads)["timestamp_us"])
        seen = self.clock.observe_host(host_s, count_us)
        starts = np.asarray(seen.starts, dtype=np.int64)
        if seen.stragglers.any():
            self.tally.add(PacketFault.LATE, int(seen.stragglers.sum()), int(index[seen.stragglers].min()))
            starts = starts - np.searchsorted(np.flatnonzero(seen.stragglers), starts)  # indices once dropped
            keep = ~seen.stragglers
            payloads, host_s, count_us, index = payloads[keep], host_s[keep], count_us[keep], index[keep]
        bounds = [0, *starts.tolist(), len(count_us)]
        sweeps: list[Sweep] = []
        for piece, (first, stop) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
            if piece > 0:  # the device clock stepped: the open sweep ends there, a new stream piece begins
                sweeps += self.flush()
                self._floor_us = None
            self._offset_s = seen.offsets_s[piece]
            part = slice(first, stop)
            sweeps += self._feed_piece(payloads[part], host_s[part], count_us[part], index[part])
        return sweeps

    def _feed_piece(
        self,
        payloads: NDArray[np.uint8],
        host_s: NDArray[np.float64],
        count_us: NDArray[np.int64],
        index: NDArray[np.int64],
    ) -> list[Sweep]:
        """Packets of one clock segment: drop late ones and duplicates, order them, cut sweeps."""
        late = count_us < self._floor_us if self._floor_us is not None else np.zeros(len(count_us), bool)
        if late.any():
            self.tally.add(PacketFault.LATE, int(late.sum()), int(index[late].min()))
            payloads, host_s, count_us, index = payloads[~late], host_s[~late], count_us[~late], index[~late]
        pending = self._pending.merged(payloads, host_s, count_us, index)
        if np.any(np.diff(pending.count_us) < 0):
            pending = pending.take(np.argsort(pending.count_us, kind="stable"))
        repeat = np.flatnonzero(np.diff(pending.count_us) == 0) + 1
        if len(repeat):
            self.tally.add(PacketFault.DUPLICATE, len(repeat), int(pending.index[repeat].min()))
            pending = pending.take(np.setdiff1d(np.arange(len(pending.count_us)), repeat))
        self._counts["data"] += len(pending.count_us) - len(self._pending.count_us)
        self._pending = pending
        return self._split() if len(pending.count_us) else []

    def _cuts(self, pending: _Pending) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Flat block indices (packet * 12 + block) after ``start_block`` where a new sweep starts, and
        whether each is a plain crossing of the cut azimuth (False: a whole turn or more went missing).

        The head's advance between consecutive blocks is the azimuth step plus the whole turns that the
        rotation rate and the elapsed time say were skipped, so a gap of any length is seen, and a block
        whose azimuth steps back a little (a corrupt one) does not pass for a crossing.
        """
        records = as_packet_records(pending.payloads)
        azimuth = records["blocks"]["azimuth"].astype(np.int64)
        dual = records["return_mode"] == ReturnMode.DUAL
        block_us = pending.count_us[:, None] + np.where(dual[:, None], _DUAL_BLOCK_US, _SINGLE_BLOCK_US)
        rate = np.repeat(packet_rate(azimuth, dual), BLOCKS_PER_PACKET)[:-1]
        azimuth, block_us = azimuth.ravel(), block_us.ravel()
        step = np.diff(azimuth) % AZIMUTH_UNITS
        turns = np.rint((rate * np.diff(block_us) - step) / AZIMUTH_UNITS)
        relative = (azimuth[:-1] - self._cut_units) % AZIMUTH_UNITS
        cuts = np.flatnonzero(relative + step + turns * AZIMUTH_UNITS >= AZIMUTH_UNITS) + 1
        later = cuts > pending.start_block
        return cuts[later], turns[cuts[later] - 1] == 0

    def _split(self, final: bool = False) -> list[Sweep]:
        pending = self._pending
        packets = len(pending.count_us)
        cuts, at_cut = self._cuts(pending)
        if not final:
            if len(cuts) == 0:
                return self._stalled()
            ready = cuts // BLOCKS_PER_PACKET < packets - self.config.reorder_window
            cuts, at_cut = cuts[ready], at_cut[ready]
            if len(cuts) == 0:
                return []
        else:
            cuts, at_cut = np.append(cuts, packets * BLOCKS_PER_PACKET), np.append(at_cut, False)
        last_packet = min(int(cuts[-1] // BLOCKS_PER_PACKET), packets - 1)
        starts_at_cut = [pending.started, *at_cut[:-1].tolist()]
        complete = [begin and end for begin, end in zip(starts_at_cut, at_cut.tolist(), strict=True)]
        sweeps = self._emit(
            pending.take(slice(0, last_packet + 1)), [pending.start_block, *cuts.tolist()], complete
        )
        if final:
            self._pending = _Pending.empty()
            return sweeps
        self._pending = replace(
            pending.take(slice(last_packet, None)),
            start_block=int(cuts[-1] % BLOCKS_PER_PACKET),
            started=bool(at_cut[-1]),
        )
        self._floor_us = int(self._pending.count_us[0])
        return sweeps

    def _stalled(self) -> list[Sweep]:
        """No cut in ``STALLED_S`` of packets: emit all but the reorder window as one incomplete sweep."""
        pending = self._pending
        end = len(pending.count_us) - self.config.reorder_window - 1  # first packet kept
        if end <= 0 or pending.count_us[end] - pending.count_us[0] < STALLED_S * 1e6:
            return []
        sweeps = self._emit(pending.take(slice(0, end + 1)), [pending.start_block, end * BLOCKS_PER_PACKET], [False])
        self._pending = replace(pending.take(slice(end, None)), start_block=0, started=False)
        self._floor_us = int(self._pending.count_us[0])
        return sweeps

    def _emit(self, packets: _Pending, bounds: list[int], complete: list[bool]) -> list[Sweep]:
        """Decode ``packets`` once and cut the sweeps [bounds[i], bounds[i+1]) (flat block indices) out."""
        decoded = decode_packets(packets.payloads, self.config.calibration, np.zeros(len(packets.count_us)))
        per_block = decoded.points_per_block.ravel()
        offsets = np.concatenate([[0], np.cumsum(per_block)])
        emitted = _Emission(packets, as_packet_records(packets.payloads), per_block)
        return [
            self._sweep(emitted, decoded.points[offsets[first] : offsets[stop]], first, stop, whole)
            for first, stop, whole in zip(bounds[:-1], bounds[1:], complete, strict=True)
        ]

    def _sweep(self, emitted: _Emission, points: np.ndarray, first: int, stop: int, complete: bool) -> Sweep:
        """One sweep of blocks [first, stop); ``points``: its own slice of the decode, times made relative."""
        count_us, dual = emitted.packets.count_us, emitted.dual
        p0, p_last = first // BLOCKS_PER_PACKET, (stop - 1) // BLOCKS_PER_PACKET
        p_end = min(stop // BLOCKS_PER_PACKET, len(count_us) - 1)  # packet of the next sweep's start
        mode = ReturnMode(int(emitted.records["return_mode"][p0]))
        start_delay_us = _block_delay_us(first % BLOCKS_PER_PACKET, bool(dual[p0]))
        # Decoded times are firing delays after each packet stamp; shift them per block, from integers, so a
        # sweep's times do not depend on how the stream was batched.
        block_packet = np.arange(first, stop) // BLOCKS_PER_PACKET
        shift_s = (count_us[block_packet] - count_us[p0]) * 1e-6 - start_delay_us * 1e-6
        points["time"] += np.repeat(shift_s, emitted.per_block[first:stop])
        last_delay_us = _block_delay_us((stop - 1) % BLOCKS_PER_PACKET, bool(dual[p_last]))
        end_us = count_us[p_last] + last_delay_us + SEQUENCE_US + (LASERS - 1) * FIRING_US  # last firing
        missing = _missing_packets(count_us[p0 : p_end + 1], emitted.packets.host_s[p0 : p_end + 1],
                                   mode.packet_period_us)
        self._counts["missing"] += missing
        epoch_s = float(self.clock.epoch_s(0))
        start_us = float(count_us[p0]) + start_delay_us
        received = slice(p0, p_last + 1)
        receive_offset_s = float(np.min(emitted.packets.host_s[received] - (epoch_s + count_us[received] * 1e-6)))
        rpm = float(np.median(emitted.rate[p0 : p_last + 1])) * 1e6 / AZIMUTH_UNITS * 60.0
        block_us = (1 if dual[p0] else 2) * SEQUENCE_US  # a dual-return block pair shares its firings
        coverage = (stop - first) * block_us * rpm / 60e6 if rpm > 0 else 0.0
        sweep = Sweep(
            index=self._next_index,
            points=points,
            start=TimePair(float(emitted.packets.host_s[p0]), epoch_s + start_us * 1e-6),
            end=TimePair(float(emitted.packets.host_s[p_last]), epoch_s + float(end_us) * 1e-6),
            packet_count=p_last - p0 + 1,
            missing_packets=missing,
            rpm=rpm,
            return_mode=mode,
            complete=complete,
            time_source=self.clock.source,
            clock_offset_s=self._offset_s,
            pps=self.clock.pps,
            receive_offset_s=receive_offset_s,
            coverage=coverage,
        )
        self._next_index += 1
        return sweep


def _missing_packets(count_us: NDArray[np.int64], host_s: NDArray[np.float64], period_us: float) -> int:
    """Packets missing between the first and last of ``count_us`` (device us, in order), received at ``host_s``.

    A gap counts by device time, unless the device clock ran ahead of the receive times across it by more
    than ``CLOCK_STEP_S``: the clock stepped (a +10 s step would be 7,535 phantom packets), and only the
    packets the host's own gap had room for can have gone missing there.
    """
    gap_us = np.diff(count_us).astype(np.float64)
    host_gap_us = np.diff(host_s) * 1e6
    stepped = gap_us - host_gap_us > CLOCK_STEP_S * 1e6
    span_us = float(np.where(stepped, np.maximum(host_gap_us, period_us), gap_us).sum())
    return max(round(span_us / period_us) - len(gap_us), 0)


class _Emission:
    """Packets decoded together: their records, dual flags (P,), rates (P,) units/us, points per block."""

    def __init__(self, packets: _Pending, records: np.ndarray, per_block: NDArray[np.int64]) -> None:
        self.packets = packets
        self.records = records
        self.per_block = per_block
        self.dual = records["return_mode"] == ReturnMode.DUAL
        self.rate = packet_rate(records["blocks"]["azimuth"].astype(np.int64), self.dual)
