"""The jackknife over the LiDAR's rings (calib.assess): a bias that every place shares, because it lies in one
ring's edge points, is invisible to the jackknife over places and seen by the one over rings; where the rings
agree it adds nothing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from calib.assess import TrustOptions, _uncertainty
from calib.edges_points import EdgePoints
from calib.geometry import Transform
from calib.gmm import GmmOptions, PairFeatures
from calib.optimize import OptimOptions
from tests.calib.synthetic import TRUTH, make_pair

RINGS = 8
OPTS = OptimOptions(sigmas_deg=(3.52, 1.76))


def with_rings(feat: PairFeatures, place: int, biased_ring: int | None = None, roll_deg: float = 0.0) -> PairFeatures:
    """``feat`` with its edge points numbered into ``RINGS`` elevation bands (the same bands in every place),
    and the points of ``biased_ring`` turned by ``roll_deg`` about the LiDAR's x axis."""
    p = feat.points.points_lidar
    elevation = np.degrees(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1])))
    ring = np.clip(np.floor((elevation + 30.0) / 60.0 * RINGS), 0, RINGS - 1).astype(np.int64)
    if biased_ring is not None:
        turn = Transform.from_rpy_xyz(np.array([roll_deg, 0.0, 0.0]), np.zeros(3))
        p = np.where((ring == biased_ring)[:, None], turn.apply(p), p)
    points = EdgePoints(p, feat.points.score, feat.points.kind, ring)
    return dataclasses.replace(feat, points=points, place=place)


@pytest.fixture(scope="module")
def pairs() -> list[PairFeatures]:
    return [make_pair(seed) for seed in range(1, 6)]


def uncertainty(feats: list[PairFeatures]):
    return _uncertainty(feats, TRUTH.tau, OPTS, GmmOptions(), None, TrustOptions(), None)


def test_a_ring_biased_in_every_place_is_seen_by_the_ring_jackknife_only(pairs: list[PairFeatures]) -> None:
    counts = np.bincount(np.concatenate([with_rings(f, i).points.ring for i, f in enumerate(pairs)]),
                         minlength=RINGS)
    busiest = int(np.argmax(counts))
    clean = uncertainty([with_rings(f, i) for i, f in enumerate(pairs)])
    biased = uncertainty([with_rings(f, i, busiest, 1.0) for i, f in enumerate(pairs)])
    assert clean.jackknife_rings is not None and clean.ring_groups == RINGS
    assert biased.jackknife is not None and biased.jackknife_rings is not None
    # Every place carries the same bias: leaving out a place does not reveal it, leaving out the ring does.
    assert biased.jackknife_rings[0] > 3.0 * biased.jackknife[0]
    assert biased.jackknife_rings[0] > 3.0 * clean.jackknife_rings[0]
    assert biased.sigma[0] == pytest.approx(max(biased.laplace[0], biased.jackknife[0], biased.jackknife_rings[0]))
    # Consistent rings: the ring jackknife is of the size of the others, not a new source of doubt.
    assert clean.jackknife is not None and clean.jackknife_rings[0] < 3.0 * max(clean.jackknife[0], clean.laplace[0])


def test_without_rings_there_is_no_ring_jackknife(pairs: list[PairFeatures]) -> None:
    unknown = uncertainty([dataclasses.replace(f, place=i) for i, f in enumerate(pairs)])
    assert unknown.jackknife_rings is None and unknown.ring_groups == 0
    assert np.allclose(unknown.sigma, np.maximum(unknown.laplace, unknown.jackknife))
