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
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

import numpy as np

from calib.assess import Assessment, Status, TrustOptions, disputed_axes, restarts_elsewhere
from calib.uncertainty import AXES

TRANSLATION = ("x", "y", "z")
ROTATION = ("roll", "pitch", "yaw")
MEASURED_PAIRS = 12  # the paper's and docs/results.md's protocols
MAX_USEFUL_PAIRS = 60  # beyond this, more of the same scenes is not the answer
NEAR_M = 10.0  # edges beyond this typical range tie the translation loosely: ask for nearer structure


class Action(Enum):
    """What a step asks the operator to do; the CLI and the page each say how (an option, a button)."""

    LEVER_ARM = "prior"  # give the lever arm from the rig's drawing
    FIX_TRANSLATION = "fix"  # hold the translation at the lever arm
    SEARCH = "search"  # start from the global search
    CLOSER_START = "init"  # give a closer initial guess
    CAPTURE = "capture"  # capture more pairs at new places (``Step.pairs`` in all)
    FIT_ELEVATION = "fit-elevation"  # fit the LiDAR's elevation offset on a set that can tell it, then declare it
    KEEP_ACTIVE = "keep-active"  # do not use this result


@dataclass(frozen=True)
class Step:
    """One thing to do next: its words, the actions it asks for, the axes it is about, and for a capture the
    pairs to have in all."""

    text: str
    actions: tuple[Action, ...] = ()
    axes: tuple[str, ...] = ()
    pairs: int | None = None


class SceneFacts(NamedTuple):
    """``pairs``: how many pairs were calibrated; ``typical_range_m``: harmonic mean range of the edge points
    (m); ``pixels_per_radian``: the camera's scale; ``translation_prior``: a translation prior or a fixed
    translation was used; ``pair_names``: each pair's folder, ``pairs/NNNN`` (empty: named by position);
    ``place_of``: each pair's place (rigd.dataset.places; empty: each pair a place of its own)."""

    pairs: int
    typical_range_m: float
    pixels_per_radian: float
    translation_prior: bool
    pair_names: tuple[str, ...] = ()
    place_of: tuple[int, ...] = ()

    @property
    def places(self) -> int:
        """How many places: only these are independent evidence (the jackknife leaves out places)."""
        return len(set(self.place_of)) if self.place_of else self.pairs

    def in_all(self, places: int) -> int:
        """The pairs a dataset holds in all with one pair at each new place up to ``places``."""
        return self.pairs + max(places - self.places, 0)


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


def _pair_names(places: tuple[int, ...], facts: SceneFacts) -> str:
    """The pairs of ``places`` by their folders (a dataset whose pairs were pruned is not numbered by position);
    a place of several pairs as all of them."""
    of = facts.place_of or tuple(range(facts.pairs))
    names = [" + ".join(_pair_name(i, facts) for i, p in enumerate(of) if p == place) or _pair_name(place, facts)
             for place in places]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def _more_pairs(axes: list[str], a: Assessment, facts: SceneFacts, trust: TrustOptions) -> Step | None:
    if not axes:
        return None
    held_by = a.uncertainty.held_by
    named = tuple(axes)
    if held_by:  # the jackknife's sigma is how far the pose slides without one place: no 1/sqrt(pairs) count
        either = "it" if len(held_by) == 1 else "any one of them"
        return Step(f"{', '.join(axes)}: the pose rests on {_pair_names(held_by, facts)}: without {either} "
                    "the other pairs' edges do not hold it, and the sigma is how far it then slides, not noise that "
                    "averages away; capture more pairs at new places with structure like theirs (see their overlays)",
                    (Action.CAPTURE,), named, facts.in_all(max(facts.places + len(held_by), MEASURED_PAIRS)))
    idx = [AXES.index(ax) for ax in axes]
    sigma = a.uncertainty.sigma[idx]
    if not np.all(np.isfinite(sigma)):
        return None
    needed = _pairs_needed(sigma, trust.tolerance_display[idx], trust.sigma_factor, facts.places)
    names = ", ".join(axes)
    if needed > MAX_USEFUL_PAIRS:
        return Step(f"{names}: more pairs of scenes like these would not do it (about {needed} needed at the rate "
                    "sigma falls); capture in places with more distinct edges (buildings, poles, doorways) in several "
                    "directions", (), named)
    # Never fewer than rigd is measured with: the estimate moves with each calibration's sigma (4 pairs asked for
    # 8, then those 8 for 11), and one target, the one the "only N pairs" step names too, is what a capture needs.
    target = max(needed, MEASURED_PAIRS)
    return Step(f"{names}: capture more pairs at new places and headings, about {target} places in all (sigma "
                f"falls roughly as 1/sqrt(places); now {_counted(facts)}), and keep the rig still during each capture",
                (Action.CAPTURE,), named, facts.in_all(target))


def _counted(facts: SceneFacts) -> str:
    """``12`` places, or ``20 pairs at 1 place`` where pairs share places."""
    pairs = "1 pair" if facts.pairs == 1 else f"{facts.pairs} pairs"
    places = "1 place" if facts.places == 1 else f"{facts.places} places"
    return str(facts.places) if facts.places == facts.pairs else f"{pairs} at {places}"


def ring_set(axes: list[str], a: Assessment) -> list[str]:
    """The ``axes`` whose sigma the jackknife over the LiDAR's rings sets (larger than the other sources)."""
    u = a.uncertainty
    if u.jackknife_rings is None:
        return []
    others = u.laplace if u.jackknife is None else np.maximum(u.laplace, u.jackknife)
    return [ax for ax in axes if u.jackknife_rings[AXES.index(ax)] > others[AXES.index(ax)]]


def _worst(axes: list[str], part: np.ndarray) -> tuple[str, str, float]:
    """The axis of ``axes`` with the largest ``part`` (deg and cm weighed 1 : 10), its unit and value."""
    worst = max(axes, key=lambda ax: part[AXES.index(ax)] / (1.0 if ax in ROTATION else 10.0))
    return worst, "deg" if worst in ROTATION else "cm", float(part[AXES.index(worst)])


def _rings(axes: list[str], a: Assessment) -> Step | None:
    if not axes:
        return None
    worst, unit, value = _worst(axes, a.uncertainty.sigma)
    return Step(f"{', '.join(axes)}: the result depends on which of the LiDAR's rings cross the scenes' edges "
                f"(leaving out one ring moves {worst} by {value:.2g} {unit} at 1 sigma): sparse rings sample sloping "
                "and horizontal edges at few heights, and in every place alike; capture places whose edges stand at "
                "other heights and distances from the rig (buildings, poles, doorways 2-10 m away), or give the "
                "lever arm from the rig's drawing", (Action.CAPTURE, Action.LEVER_ARM), tuple(axes))


def elevation_set(axes: list[str], a: Assessment) -> list[str]:
    """The ``axes`` whose sigma the LiDAR's elevation offset (fitted or declared) sets: its part is the larger."""
    u = a.uncertainty
    if u.elevation is None:
        return []
    data = np.sqrt(np.maximum(np.square(u.sigma) - np.square(u.elevation), 0.0))
    return [ax for ax in axes if u.elevation[AXES.index(ax)] > data[AXES.index(ax)]]


def _cross_check(axes: list[str], a: Assessment) -> Step | None:
    part = a.uncertainty.cross_check
    if not axes or part is None:
        return None
    worst, unit, value = _worst(axes, part * np.sqrt(2.0))
    return Step(f"{', '.join(axes)}: the image's edges and its intensities disagree (the GMM's edges refined from "
                f"NID's answer move {worst} by {value:.2g} {unit}), a bias that neither sees alone and more pairs "
                "like these do not narrow; check the camera's intrinsics (K, D) against a recent calibration, and "
                "capture places with distinct edges 2-10 m away", (Action.CAPTURE,), tuple(axes))


def _elevation(axes: list[str], a: Assessment) -> Step | None:
    part = a.uncertainty.elevation
    if not axes or part is None:
        return None
    worst, unit, value = _worst(axes, part)
    return Step(f"{', '.join(axes)}: the LiDAR's elevation offset is not known well enough (its sigma alone moves "
                f"{worst} by {value:.2g} {unit} at 1 sigma), and more pairs like these do not narrow it; fit the "
                "offset where rings cross edges at many heights (a denser LiDAR's set, or places with near slopes "
                "and edges' ends) and declare it", (Action.FIT_ELEVATION,), tuple(axes))


def _translation(axes: list[str], facts: SceneFacts) -> Step | None:
    if not axes or facts.translation_prior:
        return None
    px_per_cm = facts.pixels_per_radian * 0.01 / max(facts.typical_range_m, 1e-3)
    seen = (f"{', '.join(axes)}: translation is seen only through parallax; at these scenes' typical edge range "
            f"({facts.typical_range_m:.0f} m) 1 cm moves an edge {px_per_cm:.2g} px")
    actions = (Action.LEVER_ARM, Action.FIX_TRANSLATION)
    if facts.typical_range_m > NEAR_M:
        return Step(f"{seen}; capture pairs with structure 2-{NEAR_M:g} m from the rig, or give the lever arm from "
                    "the rig's drawing (or hold the translation at it)", (Action.CAPTURE, *actions), tuple(axes),
                    facts.in_all(MEASURED_PAIRS) if facts.places < MEASURED_PAIRS else None)
    return Step(f"{seen}; give the lever arm from the rig's drawing (or hold the translation at it)", actions,
                tuple(axes))


def _start_steps(a: Assessment, trust: TrustOptions) -> list[Step]:
    """What the solve's path says: no minimum, a run far from its start, a translation pulled far."""
    steps = []
    if not a.uncertainty.is_minimum:
        steps.append(Step("the finest level did not end at a minimum: look at the 'before' overlays; if the edge "
                          "dots are far from the image's edges, give a closer initial guess or let the global search "
                          "find one", (Action.CLOSER_START, Action.SEARCH)))
    if a.moved_deg is not None and a.moved_deg > trust.max_move_deg:
        steps.append(Step(f"the solve ran {a.moved_deg:.0f} deg from its start: look at the 'before' overlays; if "
                          "the edge dots already sat near the image's edges, the scenes hold another alignment as "
                          "strong (add pairs with buildings, poles or doorways); if not, give a closer initial guess "
                          "or use the global search", (Action.CLOSER_START, Action.SEARCH)))
    if a.moved_m is not None and a.moved_m > trust.max_move_m:
        steps.append(Step(f"the translation ran {a.moved_m:.1f} m from its start: check the lever arm given and its "
                          "unit", (Action.LEVER_ARM,), TRANSLATION))
    return steps + _given_steps(a, trust)


def _given_steps(a: Assessment, trust: TrustOptions) -> list[Step]:
    """What the values given (the lever arm, the rotation prior, a held translation) say against the data."""
    ev = a.evidence
    if ev is None:
        return []
    steps = []
    rot_z, trans_z = ev.prior_z
    if trans_z is not None and trans_z > trust.prior_max_z:
        steps.append(Step(f"the translation lies {trans_z:.0f} sigma from the lever arm given: check it and its unit "
                          "(a lever arm in metres where cm are asked for is a hundredth of the rig's)",
                          (Action.LEVER_ARM,), TRANSLATION))
    if rot_z is not None and rot_z > trust.prior_max_z:
        steps.append(Step(f"the rotation lies {rot_z:.0f} sigma from the rotation prior given: check it", (),
                          ROTATION))
    if ev.fixed_worse_nll is not None and ev.fixed_worse_nll > trust.fixed_worse_nll:
        steps.append(Step(f"{', '.join(ev.fixed)} held at the values given fit clearly worse than free: check the "
                          "lever arm given and its unit, or let the translation free", (Action.LEVER_ARM,), ev.fixed))
    return steps


def _fit_steps(a: Assessment, trust: TrustOptions) -> list[Step]:
    """What the restarts say: another pose as good, or minima that do not agree."""
    steps = []
    tol = trust.tolerance_display
    ties = [r for r in a.restarts if r.delta_nll < trust.ambiguity_nll and bool((np.abs(r.offset) > tol).any())]
    if ties:
        which = "the first solution" if ties[0].origin == "solution" else ties[0].origin
        steps.append(Step(f"another pose fits these pairs as well ({which}): the scenes' edges are too few or "
                          "repeat; add pairs in other places", (Action.CAPTURE,)))
    if restarts_elsewhere(a.uncertainty, list(a.restarts), trust) is not None:
        steps.append(Step("restarts near the solution ended at other minima: the LiDAR edges do not line up with "
                          "the image's in one clear way; look at the 'after' overlays for edges on foliage or "
                          "texture, check the camera model (K, D) and that the rig stood still, and capture scenes "
                          "with buildings, poles or doorways", (Action.CAPTURE,)))
    return steps


def next_steps(a: Assessment, facts: SceneFacts, trust: TrustOptions) -> tuple[Step, ...]:
    """What to do next, most useful first; empty for a trusted result."""
    v = a.verdict
    if v.status is Status.TRUSTED:
        return ()
    steps: list[Step | None] = [*_start_steps(a, trust)]
    weak_t = [ax for ax in TRANSLATION if ax in v.weak_axes]
    weak_r = [ax for ax in ROTATION if ax in v.weak_axes]
    steps.append(_translation(weak_t, facts))
    steps.extend(_fit_steps(a, trust))
    counted = weak_r + ([] if facts.translation_prior else weak_t)
    by_elevation = elevation_set(counted, a)
    steps.append(_elevation(by_elevation, a))
    counted = [ax for ax in counted if ax not in by_elevation]
    by_cross_check = [ax for ax in counted if ax in disputed_axes(a.uncertainty, trust)]
    steps.append(_cross_check(by_cross_check, a))
    counted = [ax for ax in counted if ax not in by_cross_check]
    by_rings = ring_set(counted, a)
    steps.append(_rings(by_rings, a))
    steps.append(_more_pairs([ax for ax in counted if ax not in by_rings], a, facts, trust))
    if facts.places < MEASURED_PAIRS:
        have = ("1 pair" if facts.pairs == 1 else f"{facts.pairs} pairs") if facts.places == facts.pairs \
            else _counted(facts)
        steps.append(Step(f"only {have}: rigd is measured with {MEASURED_PAIRS} places (move the rig between "
                          "captures: pairs at one place see the same scene alike)", (Action.CAPTURE,),
                          pairs=facts.in_all(MEASURED_PAIRS)))
    if v.status is Status.FAILED:
        steps.append(Step("do not use this result: keep the active calibration (the service does not activate it)",
                          (Action.KEEP_ACTIVE,)))
    return tuple(s for s in steps if s is not None)
