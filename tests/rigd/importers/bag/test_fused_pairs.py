"""A VelodyneScan bag's pair holds the sweeps capture would fuse (rigd.capture.fuse.sweeps_for_frame: in the
still window, the ``sweeps`` nearest the image), fused by rigd.capture.fuse.fuse_sweeps, not one sweep."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from rigd.capture.fuse import fuse_sweeps, sweeps_for_frame
from rigd.dataset.pcd import read_pcd
from rigd.importers.bag import BagImportOptions, import_bag
from rigd.importers.bag.clouds import velodyne_scan_vlp16
from rigd.importers.bag.reader import CLOUD_KINDS, Bag
from rigd.importers.bag.stills import StillOptions
from tests.rigd.importers.bag.bags import BagFormat, stops, write_bag

SWEEPS = 5


def test_sweeps_for_frame_takes_the_nearest_inside_the_window_in_time_order() -> None:
    spans = [(0.1 * k, 0.1 * k + 0.09) for k in range(10)]
    assert sweeps_for_frame(spans, 0.52, (0.1, 0.99), 3) == [4, 5, 6]
    assert sweeps_for_frame(spans, 0.0, (0.1, 0.99), 3) == [1, 2, 3]  # sweep 0 starts before the window
    assert sweeps_for_frame(spans, 0.52, (0.1, 0.99), 1) == [5]
    assert sweeps_for_frame(spans, 0.52, (0.35, 0.5), 3) == [4]  # only one lies wholly inside


@pytest.fixture(scope="module")
def imported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A bag of one stop (12 real, distinct turns) imported with ``sweeps=5``: (bag, dataset)."""
    folder = tmp_path_factory.mktemp("fused")
    recording = stops(yaws_deg=[0.0], still_sweeps=12, move_sweeps=0)
    bag = write_bag(folder / "run", BagFormat.MCAP, recording)
    options = BagImportOptions(recording.image_topic, recording.cloud_topic, recording.info_topic,
                               still=StillOptions(still_seconds=0.5, sweeps=SWEEPS))
    summary = import_bag(bag, folder / "out", options=options)
    assert summary.pairs == 1
    return bag, folder / "out"


def test_pair_cloud_is_capture_fusion_of_the_nearest_sweeps(imported: tuple[Path, Path]) -> None:
    bag_path, out = imported
    meta = yaml.safe_load((out / "pairs" / "0000" / "meta.yaml").read_text())
    cloud = read_pcd(out / "pairs" / "0000" / "cloud.pcd")
    with Bag(bag_path) as bag:
        topic = bag.topic(name=meta["lidar"]["topic"], kinds=CLOUD_KINDS, role="--cloud-topic")
        decoded = [velodyne_scan_vlp16(m.body, where=m.topic) for m in bag.messages(topics=[topic])]
    sweeps = [s for s in decoded if s is not None]
    spans = [(s.start.device, s.end.device) for s in sweeps]
    window = meta["still_window_s"]
    chosen = sweeps_for_frame(spans, meta["camera"]["stamp_s"], (window[0], window[1]), SWEEPS)
    assert len(chosen) == SWEEPS and meta["lidar"]["sweeps"] == SWEEPS
    assert meta["lidar"]["sweep_stamps_s"] == [list(spans[k]) for k in chosen]
    fused = fuse_sweeps([sweeps[k] for k in chosen])
    assert len(cloud) == len(fused) == meta["lidar"]["points"]
    np.testing.assert_allclose(cloud.points_lidar, fused.points_lidar.astype(np.float32), atol=1e-6)
    assert cloud.ring is not None and fused.ring is not None
    np.testing.assert_array_equal(cloud.ring, fused.ring)
    # The check tells one sweep from five: the nearest sweep alone, fused or raw, is another cloud.
    nearest = sweeps_for_frame(spans, meta["camera"]["stamp_s"], (window[0], window[1]), 1)
    assert nearest[0] in chosen
    assert len(fuse_sweeps([sweeps[nearest[0]]])) != len(cloud)
    assert len(sweeps[nearest[0]].points) != len(cloud)
