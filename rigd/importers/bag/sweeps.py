"""Pass 1's sweeps: every message of the cloud topic deserialised, decoded and reduced to the stillness gate's
direction grid, in worker processes ahead of the gate.

The gate itself (rigd.capture.gate.StillnessGate) stays sequential in the importing process: each sweep is
compared with its window's anchor, which only the sweeps before it decide. What comes before it depends on one
message alone (its deserialisation, the VLP-16 decoder, the direction grid), so :class:`SweepPipeline` hands
batches of raw messages to a process pool and gives the reduced sweeps back in bag order, the same values the
importing process would compute (the same functions on the same bytes). The gate keeps one processor busy, so
by default the pool has one process less than there are processors; ``workers=0`` reduces in this process.
"""

from __future__ import annotations

import multiprocessing
import os
from collections import deque
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from types import TracebackType

from rigd.capture.gate import DirectionGrid, direction_grid
from rigd.importers.bag.clouds import BagSweep, pointcloud2_sweep, velodyne_scan_sweep
from rigd.importers.bag.reader import Bag, Deserializer, Message, RawMessage, TopicKind
from rigd.importers.bag.stills import SweepTime

BATCH = 8  # messages per task: ~0.7 MB of VLP-16 packets, ~70 ms of work
IN_FLIGHT_PER_WORKER = 3  # tasks queued ahead of the gate per worker: bounds the memory the pipeline holds


def where(message: Message) -> str:
    """A message named in errors: its topic and stamp."""
    return f"{message.topic} at {message.stamp_s:.6f} s"


def decode_sweep(message: Message, kind: TopicKind) -> BagSweep | None:
    """A cloud-topic message as a sweep (None: a VelodyneScan without a valid packet)."""
    if kind is TopicKind.VELODYNE_SCAN:
        return velodyne_scan_sweep(message.body, where=where(message))
    return pointcloud2_sweep(message.body, stamp_s=message.stamp_s, where=where(message))


@dataclass(frozen=True)
class ReducedSweep:
    """A cloud message as pass 1 keeps it: bag time ns, the header's frame id, the sweep's span and its direction
    grid (both None when the message holds no valid return; its points are not kept)."""

    bag_time_ns: int
    frame_id: str
    time: SweepTime | None
    grid: DirectionGrid | None


def reduce_sweep(message: Message, kind: TopicKind) -> ReducedSweep:
    """``message`` decoded and reduced to the gate's direction grid."""
    sweep = decode_sweep(message, kind)
    if sweep is None or len(sweep) == 0:
        return ReducedSweep(message.bag_time_ns, message.frame_id, None, None)
    return ReducedSweep(message.bag_time_ns, message.frame_id, SweepTime(sweep.t_start_s, sweep.t_end_s),
                        direction_grid(sweep.points_lidar, sweep.ring))


@dataclass(frozen=True)
class _Job:
    """What a worker process reduces with: the bag's message definitions and the cloud topic's kind."""

    deserializer: Deserializer
    kind: TopicKind


_WORKER_JOB: list[_Job] = []  # set once in each worker process by _start_worker


def _start_worker(job: _Job) -> None:
    _WORKER_JOB.append(job)


def _reduce_batch(batch: list[RawMessage]) -> list[ReducedSweep]:
    job = _WORKER_JOB[-1]
    return [reduce_sweep(job.deserializer.message(raw), job.kind) for raw in batch]


def default_workers() -> int:
    """Processes to reduce sweeps beside the gate's: one less than the processors this process may run on."""
    affinity = getattr(os, "sched_getaffinity", None)
    processors = len(affinity(0)) if affinity is not None else os.cpu_count() or 1
    return processors - 1


class SweepPipeline:
    """Reduces the cloud topic's raw messages (:meth:`put`, in bag order) in ``workers`` processes (0: in this
    one); :meth:`put` and :meth:`finish` give back the reduced sweeps in the same order as they are ready. Use as a
    context manager."""

    def __init__(self, *, bag: Bag, kind: TopicKind, workers: int) -> None:
        self._bag, self._kind = bag, kind
        self._batch: list[RawMessage] = []
        self._pending: deque[Future[list[ReducedSweep]]] = deque()
        self._pool: ProcessPoolExecutor | None = None
        if workers > 0:
            methods = multiprocessing.get_all_start_methods()  # fork: the workers need not import rigd again
            context = multiprocessing.get_context("fork" if "fork" in methods else None)
            self._pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_start_worker,
                                             initargs=(_Job(bag.deserializer(), kind),))
        self._limit = IN_FLIGHT_PER_WORKER * max(workers, 1)

    def __enter__(self) -> SweepPipeline:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)

    def put(self, raw: RawMessage) -> list[ReducedSweep]:
        """Take the next cloud message; returns the sweeps reduced by now, in order (maybe none)."""
        if self._pool is None:
            return [reduce_sweep(self._bag.message(raw), self._kind)]
        self._batch.append(raw)
        if len(self._batch) >= BATCH:
            self._pending.append(self._pool.submit(_reduce_batch, self._batch))
            self._batch = []
        ready: list[ReducedSweep] = []
        while self._pending and (self._pending[0].done() or len(self._pending) > self._limit):
            ready += self._pending.popleft().result()
        return ready

    def finish(self) -> list[ReducedSweep]:
        """The sweeps still on their way, in order."""
        if self._pool is None:
            return []
        if self._batch:
            self._pending.append(self._pool.submit(_reduce_batch, self._batch))
            self._batch = []
        ready: list[ReducedSweep] = []
        while self._pending:
            ready += self._pending.popleft().result()
        return ready
