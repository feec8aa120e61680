"""The sweeps of pass 1 reduced in worker processes (rigd/importers/bag/sweeps.py) are those reduced in process: same
order, same spans, the same direction grids to the bit, so the stillness gate selects the same pairs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigd.importers.bag.reader import CLOUD_KINDS, IMAGE_KINDS, Bag
from rigd.importers.bag.sweeps import BATCH, ReducedSweep, SweepPipeline
from tests.rigd.importers.bag.bags import BagFormat, stops, write_bag


def _reduced(bag_path: Path, workers: int) -> list[ReducedSweep]:
    with Bag(bag_path) as bag:
        cloud = bag.topic(name="/velodyne_packets", kinds=CLOUD_KINDS, role="--cloud-topic")
        image = bag.topic(name="/camera/image/compressed", kinds=IMAGE_KINDS, role="--image-topic")
        out: list[ReducedSweep] = []
        with SweepPipeline(bag=bag, kind=cloud.kind, workers=workers) as pipeline:
            for raw in bag.raw_messages(topics=[cloud, image]):  # images between the sweeps, as pass 1 reads
                if raw.topic == cloud.name:
                    out += pipeline.put(raw)
            out += pipeline.finish()
    return out


@pytest.mark.parametrize("fmt", [BagFormat.ROS1, BagFormat.MCAP])
def test_workers_reduce_what_the_process_reduces(tmp_path: Path, fmt: BagFormat) -> None:
    recording = stops(yaws_deg=[0.0, 30.0], still_sweeps=BATCH + 3, move_sweeps=2)  # batches and a remainder
    bag = write_bag(tmp_path / ("run.bag" if fmt is BagFormat.ROS1 else "run"), fmt, recording)
    here, pooled = _reduced(bag, 0), _reduced(bag, 2)
    assert len(here) == len(pooled) == len(recording.sweeps)
    assert [s.bag_time_ns for s in pooled] == sorted(s.bag_time_ns for s in pooled)
    for a, b in zip(here, pooled, strict=True):
        assert (a.bag_time_ns, a.frame_id, a.time) == (b.bag_time_ns, b.frame_id, b.time)
        assert a.grid is not None and b.grid is not None
        for name in ("range_m", "points", "spread_m", "count"):
            assert np.array_equal(getattr(a.grid, name), getattr(b.grid, name), equal_nan=True), name
    yaws = {yaw for _, yaw in recording.sweeps}
    first = {yaw: next(s for s, (_, y) in zip(here, recording.sweeps, strict=True) if y == yaw) for yaw in yaws}
    assert not np.array_equal(first[0.0].grid.range_m, first[30.0].grid.range_m, equal_nan=True)  # type: ignore[union-attr]
