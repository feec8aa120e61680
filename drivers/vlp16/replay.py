"""File source: sweeps from a pcap/pcapng capture, optionally paced to the capture's own timing."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

from drivers.vlp16.pcap import CaptureSummary, Ports, read_batches
from drivers.vlp16.sweep import StreamStats, Sweep, SweepAssembler, Vlp16Config


class PcapReplay:
    """Iterate to get the :class:`Sweep` records of a capture; :attr:`stats` afterwards (or during).

    ``speed``: None replays as fast as possible; a number paces the sweeps to the capture's host time
    divided by it (1.0 = real time). Raises CaptureFileError if the file is not a readable capture.
    """

    def __init__(
        self,
        path: Path,
        config: Vlp16Config | None = None,
        ports: Ports | None = None,
        speed: float | None = None,
    ) -> None:
        self.path = Path(path)
        self.config = config or Vlp16Config()
        self.ports = ports or Ports()
        self.speed = speed
        self.summary = CaptureSummary()
        self._assembler = SweepAssembler(self.config)

    @property
    def stats(self) -> StreamStats:
        return self._assembler.stats()

    def __iter__(self) -> Iterator[Sweep]:
        clock_start: tuple[float, float] | None = None  # (first sweep end host s, wall clock then)
        for sweeps in self._sweep_groups():
            for sweep in sweeps:
                if self.speed is not None:
                    clock_start = clock_start or (sweep.end.host, time.monotonic())
                    due = clock_start[1] + (sweep.end.host - clock_start[0]) / self.speed
                    time.sleep(max(0.0, due - time.monotonic()))
                yield sweep

    def _sweep_groups(self) -> Iterator[list[Sweep]]:
        for batch in read_batches(self.path, self.ports, summary=self.summary):
            yield self._assembler.feed(batch)
        yield self._assembler.flush()


def read_sweeps(path: Path, config: Vlp16Config | None = None) -> tuple[list[Sweep], StreamStats]:
    """All sweeps of a capture file and the stream statistics."""
    replay = PcapReplay(path, config)
    return list(replay), replay.stats
