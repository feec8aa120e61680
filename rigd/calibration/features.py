"""A dataset's features for a calibration: the GMM's edges and the photometric costs' arrays of every pair, one
per view (one camera, or each sensor of a head), ordered view by view; and where they are made: the edge threads
and the job's worker pool."""

from __future__ import annotations

import ctypes
import dataclasses
import multiprocessing
import os
import sys
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, ThreadPoolExecutor, as_completed
from contextlib import contextmanager
from typing import NamedTuple, TypeVar

from calib.errors import FeaturelessError
from calib.gmm import PairFeatures
from calib.methods import SolveRequest
from calib.photometric import PhotoCost, PhotoPair, PhotoParams, photo_pair
from calib.pipeline import CalibParams, PairInput, extract_features, extract_place
from rigd.calibration.pool import FeaturePool, preload
from rigd.calibration.progress import Progress, Stage
from rigd.dataset import Dataset, Pair
from rigd.dataset.places import dataset_places
from rigd.errors import RigdError


def _place_features(dataset: Dataset, params: CalibParams, i: int) -> list[PairFeatures]:
    """The features of pair ``i``: one per view (one camera, or each sensor of a head)."""
    pair = dataset.load_pair(i)
    cameras = list(dataset.rig.camera.models())
    if len(cameras) == 1:
        return [extract_features(PairInput(pair.image, pair.cloud.points_lidar, pair.cloud.ring, dataset.masks[0]),
                                 cameras[0], params, index=i)]
    inputs = [PairInput(image, pair.cloud.points_lidar, pair.cloud.ring, mask)
              for image, mask in zip(pair.images, dataset.masks, strict=True)]
    return extract_place(inputs, cameras, params, index=i)


def feature_at(feats: list[PairFeatures], dataset: Dataset, pair: int, view: int = 0) -> PairFeatures:
    """The features of ``view`` of ``pair`` in :func:`dataset_features`' list (ordered view by view)."""
    return feats[view * len(dataset) + pair]


def dataset_features(dataset: Dataset, params: CalibParams, progress: Progress | None,
                     executor: Executor | None = None) -> list[PairFeatures]:
    """Edge features of every pair of ``dataset``, one per view of a pair (FeaturelessError names a pair without
    enough edges), the pairs extracted side by side in ``executor`` (:func:`edge_threads`) if given, each pair a
    place of its own (:func:`features_for` gives them the places found). Ordered view by view
    (:func:`feature_at`)."""
    if len(dataset) == 0:
        raise RigdError(f"{dataset.root}: dataset has no pairs (pairs/NNNN)")
    if executor is None:
        per_pair = []
        for i in range(len(dataset)):
            if progress:
                progress(Stage.EDGES, i, len(dataset))
            per_pair.append(_place_features(dataset, params, i))
    else:
        futures = [executor.submit(_place_features, dataset, params, i) for i in range(len(dataset))]
        for done, _ in enumerate(as_completed(futures)):
            if progress:
                progress(Stage.EDGES, done + 1, len(dataset))
        per_pair = [f.result() for f in futures]
    # One camera object per view for all pairs (each pair's was made, or unpickled, on its own): the cost projects
    # and sums the pairs that share one camera object together (calib.gmm.pair_terms), not one pair at a time.
    cameras = dataset.rig.camera.models()
    return [dataclasses.replace(views[v], camera=camera, place=i) for v, camera in enumerate(cameras)
            for i, views in enumerate(per_pair)]


@contextmanager
def worker_pool(workers: int) -> Iterator[Executor | None]:
    """``workers - 1`` spawned processes beside this one for the independent solves of one calibration (the
    alternative schedules, half the restarts, the search's runners-up), or None (one worker, or inside a daemonic
    pool worker, which cannot have children). They start at once and import the solver while this process
    extracts the pairs' edges in threads (:func:`edge_threads`), and keep the features they are sent, with the
    field bands their solves build (:class:`FeaturePool`). An error or an interrupt in the caller kills them
    mid-task: no result of theirs would be read.

    Spawn, not fork (as rigd.evaluate): a child forked while OpenCV's or BLAS's own threads hold a lock can
    deadlock, and those threads are invisible to the threading module. Costs ~1 s of imports per worker."""
    if workers <= 1 or multiprocessing.current_process().daemon:
        yield None
        return
    # numba too: calib compiles its kernels at their first call (calib.compiled), here before the first task.
    pool = FeaturePool(workers - 1, initializer=preload, initargs=("calib.assess", "numba"))
    try:
        yield pool
    except BaseException:  # an error or an interrupt here: no running task's result will be read
        pool.abort()
        raise
    pool.shutdown()


@contextmanager
def edge_threads(workers: int, n_pairs: int) -> Iterator[Executor | None]:
    """Threads of this process for the pairs' edges (and overlays), as many as ``workers`` and the cores allow
    (the FFTs, OpenCV and the compiled kernels release Python's lock; measured on out51 with two workers:
    processes spent 3.4 s more CPU, their imports and copies, than one process for the same wall time), or None
    for one."""
    n = min(workers, cores(), n_pairs)
    if n <= 1:
        yield None
        return
    with ThreadPoolExecutor(n) as threads:
        yield threads


# glibc's malloc_trim (None elsewhere): each thread allocates from an arena of its own, and what the edge threads
# freed stays in those arenas, mapped, unless given back (out51: the peak RSS 318 -> 298 MiB, the same time).
_MALLOC_TRIM = getattr(ctypes.CDLL(None), "malloc_trim", None) if sys.platform.startswith("linux") else None


def return_freed_memory() -> None:
    """Give the heap that this process's threads freed back to the system (glibc), before a phase that allocates
    anew, so the process's peak does not hold both."""
    if _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)


def cores() -> int:
    """The processors this process may run on (Linux: its affinity, as a pinned service's)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


T = TypeVar("T")


def _per_pair(dataset: Dataset, stage: Stage, progress: Progress | None, make: Callable[[Pair, int], T]) -> list[T]:
    """``make(pair, index)`` for every pair of ``dataset``, reporting ``stage`` of pair i/n to ``progress``."""
    if len(dataset) == 0:
        raise RigdError(f"{dataset.root}: dataset has no pairs (pairs/NNNN)")
    out = []
    for i in range(len(dataset)):
        pair = dataset.load_pair(i)
        if progress:
            progress(stage, i, len(dataset))
        out.append(make(pair, i))
    return out


def dataset_photo_pairs(dataset: Dataset, params: PhotoParams, progress: Progress | None,
                        places: tuple[int, ...] | None = None) -> list[PhotoPair]:
    """The photometric costs' arrays of every pair, one per view, view by view as :func:`dataset_features`, each
    with its place (FeaturelessError names a pair whose cloud has no intensity)."""
    cameras = dataset.rig.camera.models()
    where = places or tuple(range(len(dataset)))
    per_pair = _per_pair(dataset, Stage.REFLECTIVITY, progress, lambda pair, i: [photo_pair(
        image, pair.cloud.points_lidar, pair.cloud.intensity, pair.cloud.ring, camera, params, index=i, mask=mask)
        for image, camera, mask in zip(pair.images, cameras, dataset.masks, strict=True)])
    return [dataclasses.replace(views[v], place=where[i]) for v in range(len(cameras))
            for i, views in enumerate(per_pair)]


def _search_photo(dataset: Dataset, progress: Progress | None) -> list[PhotoPair] | None:
    """The pairs' images and LiDAR reflectivity for the global search's score (calib.search_mi), or None when a
    cloud has no intensity (the search then scores the edges)."""
    try:
        return dataset_photo_pairs(dataset, PhotoParams(cost=PhotoCost.MI), progress)
    except FeaturelessError:  # a cloud without intensity (the message names it): nothing to compare
        return None


class Features(NamedTuple):
    """What a request's method solves on: the GMM's edges (None: not a GMM method), the photometric pairs (None:
    not a photometric method), the pairs' images and reflectivity for the global search's score (None: no search,
    or a cloud without intensity), and the place of each pair (rigd.dataset.places)."""

    gmm: list[PairFeatures] | None
    photo: list[PhotoPair] | None
    search_photo: list[PhotoPair] | None
    places: tuple[int, ...] = ()


def features_for(dataset: Dataset, solve: SolveRequest, progress: Progress | None = None,
                 workers: int = 1) -> Features:
    """The features ``solve`` needs of ``dataset``, the pairs' edges in ``workers`` threads. An assessed
    photometric method's edges are its cross-check's: a dataset too bare for them goes without one."""
    edges = solve.edges
    feats = None
    if edges is not None:
        with edge_threads(workers, len(dataset)) as threads, ThreadPoolExecutor(1) as beside:
            found = beside.submit(dataset_places, dataset)  # the clouds read while the edges are found
            feats = _edges_or_none(dataset, edges, progress, threads, needed=solve.gmm is not None)
            places = found.result()
        if feats is not None:
            feats = [dataclasses.replace(f, place=places[i % len(dataset)]) for i, f in enumerate(feats)]
        return_freed_memory()
    else:
        places = dataset_places(dataset)
    photo = dataset_photo_pairs(dataset, solve.photo, progress, places) if solve.photo is not None else None
    search = _search_photo(dataset, progress) if solve.initial is None and solve.gmm is not None else None
    return Features(feats, photo, search, places)


def _edges_or_none(dataset: Dataset, params: CalibParams, progress: Progress | None, threads: Executor | None,
                   needed: bool) -> list[PairFeatures] | None:
    """:func:`dataset_features`; when not ``needed`` (a cross-check's), None for a pair without enough edges."""
    try:
        return dataset_features(dataset, params, progress, threads)
    except FeaturelessError:
        if needed:
            raise
        return None
