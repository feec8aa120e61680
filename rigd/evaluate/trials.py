"""What every evaluation protocol shares: its settings, one calibration's task and result, and the state a
worker keeps for all its trials (one dataset's features, extracted once). Where the trials run is
:mod:`rigd.evaluate.runner`."""

from __future__ import annotations

import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
from tqdm import tqdm

from calib.assess import TrustOptions
from calib.errors import CalibError
from calib.evaluate import OutlierRule
from calib.geometry import Transform
from calib.gmm import PairFeatures
from calib.methods import Method, gmm_params, photo_params
from calib.photometric import PhotoPair
from calib.pipeline import CalibParams
from calib.prior import Prior
from rigd.calibration.service import (
    dataset_features,
    dataset_photo_pairs,
    default_method,
    params_with_sigmas,
    with_camera_model,
)
from rigd.dataset import Dataset, open_dataset
from rigd.dataset.working import WORKING_WIDTH_PX
from rigd.errors import RigdError


@dataclass(frozen=True)
class EvaluationSettings:
    """What the protocols share. ``sigmas_deg`` None: ``CalibParams()``'s schedule. ``initial``: the start
    of the reference calibration (convergence without ground truth) or of every run (precision); None: the
    dataset's rig.yaml initial_guess."""

    dataset: Path
    seed: int = 0
    workers: int = 2
    out_dir: Path | None = None  # None: DATASET/evaluation
    sigmas_deg: tuple[float, ...] | None = None
    initial: Transform | None = None
    outlier_rule: OutlierRule = OutlierRule.PER_PARAMETER
    progress: bool = True  # a tqdm bar on stderr
    cluster: str | None = None  # a Dask scheduler's address (tcp://host:8786): run there instead of `workers`
    cluster_timeout_s: float = 10.0  # for connecting to it and for its first worker
    trust: TrustOptions | None = TrustOptions()  # None: no uncertainty/verdict per run (faster, no coverage check)
    # What every run solves with (`rigd calibrate --method`); None: what `rigd calibrate` picks for the dataset
    # (rigd.calibration.service.default_method: nid-assessed on a single pinhole camera, else the GMM).
    method: Method | None = None


@dataclass(frozen=True)
class Task:
    """One calibration to run: its start and the pairs it uses."""

    index: int
    start: Transform
    pairs: tuple[int, ...]


@dataclass(frozen=True)
class Run:
    """One calibration: its pairs, start and result (None with ``error`` when it raised)."""

    index: int
    pairs: tuple[int, ...]
    start: Transform
    result: Transform | None
    error: str | None
    final_cost: float | None
    iterations: int
    wall_s: float
    sigma: tuple[float, ...] | None = None  # per-axis sigma, deg x3 and cm x3 (calib.assess)
    verdict: str | None = None


@dataclass(frozen=True)
class WorkerState:
    """What a worker keeps for all its trials: one dataset's features (the GMM's edges, the photometric
    pairs, as ``method`` needs), the settings they were made with, and the rig file's prior, which every
    trial's solve uses as `rigd calibrate` does."""

    feats: tuple[PairFeatures, ...]
    params: CalibParams
    trust: TrustOptions | None
    error: str | None  # feature extraction failed: every task re-raises it, so the parent reports it
    prior: Prior | None = None
    n_pairs: int = 0  # the dataset's pairs (feats holds one per view of each, view by view)
    method: Method = Method.RIGD
    photo: tuple[PhotoPair, ...] = ()  # one per view of each pair, view by view, for a photometric method

    def checked(self) -> WorkerState:
        """``self``, or the feature extraction's error raised."""
        if self.error is not None:
            raise RigdError(self.error)
        return self


def extract_state(root: Path, params: CalibParams, trust: TrustOptions | None,
                  method: Method = Method.RIGD) -> WorkerState:
    """``root``'s features for ``method``, or the reason there are none (raised later by the trial that needs
    them)."""
    cv2.setNumThreads(1)  # one trial per core: the workers already occupy the cores
    try:
        dataset = open_dataset(root, WORKING_WIDTH_PX)
        trust = None if trust is None else with_camera_model(trust, dataset)  # as rigd calibrate judges its result
        feats = tuple(dataset_features(dataset, params, None)) if method.uses_gmm else ()
        photo_opts = photo_params(method)
        photo = () if photo_opts is None else tuple(dataset_photo_pairs(dataset, photo_opts, None))
    except (RigdError, CalibError) as exc:
        return WorkerState((), params, trust, f"{root}: {exc}", method=method)
    return WorkerState(feats, params, trust, None, dataset.rig.prior, len(dataset), method, photo)


def calib_params(sigmas_deg: tuple[float, ...] | None, method: Method = Method.RIGD) -> CalibParams:
    """``method``'s GMM settings (``CalibParams()`` for a photometric-only method, whose solve ignores them) with
    only the sigma schedule replaced (when given), as `rigd calibrate` sets them."""
    params = gmm_params(method) or CalibParams()
    if sigmas_deg is None:
        return params
    return params_with_sigmas(params, sigmas_deg)


def method_for(settings: EvaluationSettings, dataset: Dataset) -> Method:
    """The runs' method: as asked, or what `rigd calibrate` picks for ``dataset`` from a start (every run has one)
    with rig.yaml's prior, which the runs use."""
    if settings.method is not None:
        return settings.method
    return default_method(dataset, Transform.identity(), dataset.rig.prior)


def open_for(settings: EvaluationSettings) -> Dataset:
    if settings.workers < 1:
        raise RigdError(f"--workers must be at least 1, got {settings.workers}")
    dataset = open_dataset(settings.dataset, WORKING_WIDTH_PX)
    if len(dataset) == 0:
        raise RigdError(f"{dataset.root}: dataset has no pairs (pairs/NNNN)")
    return dataset


def collect(done: Iterable[Any], total: int, desc: str, progress: bool) -> list[Any]:
    """The results of futures as ``done`` yields them, with a progress bar on stderr."""
    return [f.result() for f in tqdm(done, total=total, desc=desc, unit="run", file=sys.stderr,
                                     disable=not progress)]
