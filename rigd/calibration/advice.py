"""What an operator can do about a calibration that is not trusted, from the assessment's own numbers.

Each step follows from something the verdict measured: translation is seen only through parallax, so
edges far away hold it loosely; per-axis sigma shrinks roughly as 1/sqrt(pairs) when pairs are independent,
but not where it comes from which of a sparse LiDAR's rings cross the edges (every place samples its scene
at the same elevations); a restart that ends elsewhere as low means the scenes cannot tell two poses apart;
most restarts ending at other minima mean the edges do not agree in one clear way; where the LiDAR's
elevation offset's own sigma sets an axis's, more pairs of the same kind do not narrow it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from calib.assess import Assessment, Status, TrustOptions, restarts_elsewhere
from calib.uncertainty import AXES

TRANSLATION = ("x", "y", "z")
ROTATION = ("roll", "pitch", "yaw")
MEASURED_PAIRS = 12  # the paper's and docs/results.md's protocols
MAX_USEFUL_PAIRS = 60  # beyond this, more of the same scenes is not the answer
NEAR_M = 10.0  # edges beyond this typical range tie the translation loosely: ask for nearer structure


class SceneFacts(NamedTuple):
    """``pairs``: how many pairs were calibrated; ``typical_range_m``: harmonic mean range of the edge points
    (m); ``pixels_per_radian``: the camera's scale; ``translation_prior``: a translation prior or a fixed
    translation was used; ``pair_names``: each pair's folder, ``pairs/NNNN`` (empty: named by position)."""

    pairs: int
    typical_range_m: float
    pixels_per_radian: float
    translation_prior: bool
    pair_names: tuple[str, ...] = ()


def _pairs_needed(sigma: np.ndarray, tolerance: np.ndarray, factor: float, pairs: int) -> int:
    """Pairs that would bring ``factor * sigma`` within ``tolerance`` on every given axis if sigma falls as
    1/sqrt(pairs)."""
    ratio = float(np.max(factor * sigma / tolerance))
    return math.ceil(pairs * ratio * ratio)


def _pair_name(i: int, facts: SceneFacts) -> str:
    """Pair ``i`` by its folder; where that is not its position (a pruned dataset), with its overlays' files,
    which are numbered by position."""
    by_position = f"pairs/{i:04d}"
    folder = facts.pair_names[i] if i < len(facts.pair_names) else by_position
    return folder if folder == by_position else f"{folder} (overlays/{i:04d}_*)"


def _pair_names(indices: tuple[int, ...], facts: SceneFacts) -> str:
    """The pairs at ``indices`` by their folders (a dataset whose pairs were pruned is not numbered by position)."""
    names = [_pair_name(i, facts) for i in indices]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def _more_pairs(axes: list[str], a: Assessment, facts: SceneFacts, trust: TrustOptions) -> str | None:
    if not axes:
        return None
    held_by = a.uncertainty.held_by
    if held_by:  # the jackknife's sigma is how far the pose slides without one place: no 1/sqrt(pairs) count
        either = "it" if len(held_by) == 1 else "any one of them"
        return (f"{', '.join(axes)}: the pose rests on {_pair_names(held_by, facts)}: without {either} "
                "the other pairs' edges do not hold it, and the sigma is how far it then slides, not noise that "
                "averages away; capture more pairs at new places with structure like theirs (see their overlays)")
    idx = [AXES.index(ax) for ax in axes]
    sigma = a.uncertainty.sigma[idx]
    if not np.all(np.isfinite(sigma)):
        return None
    needed = _pairs_needed(sigma, trust.tolerance_display[idx], trust.sigma_factor, facts.pairs)
    names = ", ".join(axes)
    if needed > MAX_USEFUL_PAIRS:
        return (f"{names}: more pairs of scenes like these would not do it (about {needed} needed at the rate sigma "
                "falls); capture in places with more distinct edges (buildings, poles, doorways) in several "
                "directions")
    # Never fewer than rigd is measured with: the estimate moves with each calibration's sigma (4 pairs asked for
    # 8, then those 8 for 11), and one target, the one the "only N pairs" step names too, is what a capture needs.
    target = max(needed, MEASURED_PAIRS)
    return (f"{names}: capture more pairs at new places and headings, about {target} in all (sigma falls roughly "
            f"as 1/sqrt(pairs); now {facts.pairs}), and keep the rig still during each capture")


def ring_set(axes: list[str], a: Assessment) -> list[str]:
    """The ``axes`` whose sigma the jackknife over the LiDAR's rings sets (larger than the other sources)."""
    u = a.uncertainty
    if u.jackknife_rings is None:
        return []
    others = u.laplace if u.jackknife is None else np.maximum(u.laplace, u.jackknife)
    return [ax for ax in axes if u.jackknife_rings[AXES.index(ax)] > others[AXES.index(ax)]]


def _rings(axes: list[str], a: Assessment) -> str | None:
    if not axes:
        return None
    worst = max(axes, key=lambda ax: a.uncertainty.sigma[AXES.index(ax)] / (1.0 if ax in ROTATION else 10.0))
    k = AXES.index(worst)
    unit = "deg" if worst in ROTATION else "cm"
    return (f"{', '.join(axes)}: the result depends on which of the LiDAR's rings cross the scenes' edges (leaving "
            f"out one ring moves {worst} by {a.uncertainty.sigma[k]:.2g} {unit} at 1 sigma): sparse rings sample "
            "sloping and horizontal edges at few heights, and in every place alike; capture places whose edges "
            "stand at other heights and distances from the rig (buildings, poles, doorways 2-10 m away), or give "
            "the lever arm from the rig's drawing")


def elevation_set(axes: list[str], a: Assessment) -> list[str]:
    """The ``axes`` whose sigma the LiDAR's elevation offset (fitted or declared) sets: its part is the larger."""
    u = a.uncertainty
    if u.elevation is None:
        return []
    data = np.sqrt(np.maximum(np.square(u.sigma) - np.square(u.elevation), 0.0))
    return [ax for ax in axes if u.elevation[AXES.index(ax)] > data[AXES.index(ax)]]


def _elevation(axes: list[str], a: Assessment) -> str | None:
    part = a.uncertainty.elevation
    if not axes or part is None:
        return None
    worst = max(axes, key=lambda ax: part[AXES.index(ax)] / (1.0 if ax in ROTATION else 10.0))
    unit = "deg" if worst in ROTATION else "cm"
    return (f"{', '.join(axes)}: the LiDAR's elevation offset is not known well enough (its sigma alone moves "
            f"{worst} by {part[AXES.index(worst)]:.2g} {unit} at 1 sigma), and more pairs like "
            "these do not narrow it; fit the offset where rings cross edges at many heights (rigd calibrate "
            "--fit-elevation-offset on a denser LiDAR's set, or on places with near slopes and edges' ends) and "
            "declare it in rig.yaml (lidar: {elevation_offset_deg, elevation_offset_sigma_deg})")


def _translation(axes: list[str], facts: SceneFacts) -> str | None:
    if not axes or facts.translation_prior:
        return None
    px_per_cm = facts.pixels_per_radian * 0.01 / max(facts.typical_range_m, 1e-3)
    seen = (f"{', '.join(axes)}: translation is seen only through parallax; at these scenes' typical edge range "
            f"({facts.typical_range_m:.0f} m) 1 cm moves an edge {px_per_cm:.2g} px")
    drawing = ("the lever arm from the rig's drawing (rig.yaml prior: {xyz_m: [x, y, z], sigma_cm: 1.0}, "
               "or --fix translation)")
    if facts.typical_range_m > NEAR_M:
        return f"{seen}; capture pairs with structure 2-{NEAR_M:g} m from the rig, or give {drawing}"
    return f"{seen}; give {drawing}"


def next_steps(a: Assessment, facts: SceneFacts, trust: TrustOptions) -> tuple[str, ...]:
    """What to do next, most useful first; empty for a trusted result."""
    v = a.verdict
    if v.status is Status.TRUSTED:
        return ()
    steps: list[str | None] = []
    if not a.uncertainty.is_minimum:
        steps.append("the finest level did not end at a minimum: look at the 'before' overlays; if the edge dots "
                     "are far from the image's edges, give a closer --init or let the global search find one "
                     "(--search)")
    if a.moved_deg is not None and a.moved_deg > trust.max_move_deg:
        steps.append(f"the solve ran {a.moved_deg:.0f} deg from its start: look at the 'before' overlays; if the edge "
                     "dots already sat near the image's edges, the scenes hold another alignment as strong (add "
                     "pairs with buildings, poles or doorways); if not, give a closer --init or use --search")
    if a.moved_m is not None and a.moved_m > trust.max_move_m:
        steps.append(f"the translation ran {a.moved_m:.1f} m from its start: check the lever arm given, in metres "
                     "in the rig.yaml prior ({xyz_m: [x, y, z], sigma_cm: 1.0}) and --prior, in cm on the page")
    weak_t = [ax for ax in TRANSLATION if ax in v.weak_axes]
    weak_r = [ax for ax in ROTATION if ax in v.weak_axes]
    steps.append(_translation(weak_t, facts))
    tol = trust.tolerance_display
    ties = [r for r in a.restarts if r.delta_nll < trust.ambiguity_nll and bool((np.abs(r.offset) > tol).any())]
    if ties:
        which = "the first solution" if ties[0].origin == "solution" else ties[0].origin
        steps.append(f"another pose fits these pairs as well ({which}): the scenes' edges are too few or repeat; "
                     "add pairs in other places")
    if restarts_elsewhere(a.uncertainty, list(a.restarts), trust) is not None:
        steps.append("restarts near the solution ended at other minima: the LiDAR edges do not line up with the "
                     "image's in one clear way; look at the 'after' overlays for edges on foliage or texture, "
                     "check the camera model (K, D) and that the rig stood still, and capture scenes with "
                     "buildings, poles or doorways")
    counted = weak_r + ([] if facts.translation_prior else weak_t)
    by_elevation = elevation_set(counted, a)
    steps.append(_elevation(by_elevation, a))
    counted = [ax for ax in counted if ax not in by_elevation]
    by_rings = ring_set(counted, a)
    steps.append(_rings(by_rings, a))
    steps.append(_more_pairs([ax for ax in counted if ax not in by_rings], a, facts, trust))
    if facts.pairs < MEASURED_PAIRS:
        have = "1 pair" if facts.pairs == 1 else f"{facts.pairs} pairs"
        steps.append(f"only {have}: rigd is measured with {MEASURED_PAIRS} (rigd capture --n {MEASURED_PAIRS})")
    if v.status is Status.FAILED:
        steps.append("do not use this result: keep the active calibration (the service does not activate it)")
    return tuple(s for s in steps if s is not None)
