"""How a calibration spreads over --workers N cores (rigd.calibration.features): the pairs' edges in threads of
this process, the independent solves in N - 1 spawned workers started at once."""

from __future__ import annotations

import multiprocessing

import numpy as np
import pytest

from calib.pipeline import CalibParams
from rigd.calibration.features import cores, dataset_features, edge_threads, worker_pool
from rigd.dataset import open_dataset
from rigd.simulate import write_simulated_dataset


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds") / "indoor"
    write_simulated_dataset(root, "indoor", 3, seed=5, width=256, height=128, progress=False)
    return open_dataset(root)


def test_edges_in_threads_equal_the_serial_ones(dataset):
    serial = dataset_features(dataset, CalibParams(), None)
    with edge_threads(2, len(dataset)) as threads:
        threaded = dataset_features(dataset, CalibParams(), None, threads)
    assert len(threaded) == len(serial)
    for a, b in zip(serial, threaded, strict=True):
        np.testing.assert_array_equal(a.pixels.uv, b.pixels.uv)
        np.testing.assert_array_equal(a.points.points_lidar, b.points.points_lidar)


def test_one_worker_or_one_pair_is_one_thread():
    with edge_threads(1, 12) as one_worker, edge_threads(4, 1) as one_pair:
        assert one_worker is None and one_pair is None
    with edge_threads(64, 12) as threads:
        assert (threads is None) == (cores() == 1)


def test_the_solves_get_one_process_fewer_than_the_cores_and_start_before_any_task():
    before = set(multiprocessing.active_children())
    with worker_pool(1) as none:
        assert none is None
    with worker_pool(2) as pool:
        assert pool is not None
        started = set(multiprocessing.active_children()) - before
        assert len(started) == 1  # spawned at once, not at the first task
        assert pool.submit(sum, [1, 2]).result(timeout=60) == 3
