"""Fusing K sweeps of a still rig into one cloud: per beam, the return with the median range.

A beam is a (ring, firing azimuth) cell one firing step wide (0.2 degrees at 600 rpm); a still rig's
beams repeat from turn to turn (within that step: the head's phase drifts between turns). Per beam the
return whose range is the median of the K turns' is kept whole (its point, intensity and ring), so no
point is invented between a foreground and a background surface: a beam on a depth edge keeps one of its
real returns. The median of K ranges has about 1.25 / sqrt(K) of one return's noise for Gaussian noise.
A beam that returned in fewer than half the turns (a grazing or dark surface, a depth edge) is dropped.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from drivers.vlp16 import ReturnMode, ReturnType, Sweep
from drivers.vlp16.layout import SEQUENCE_US
from rigd.dataset import Cloud


def firing_step_deg(rpm: float) -> float:
    """Azimuth advance between two firing sequences (55.296 us) at ``rpm``, degrees."""
    return rpm / 60.0 * 360.0 * SEQUENCE_US * 1e-6


def _single_return(sweep: Sweep) -> np.ndarray:
    """The sweep's points with one return per beam: the strongest of a dual-return stream."""
    if sweep.return_mode is not ReturnMode.DUAL:
        return sweep.points
    return sweep.points[(sweep.points["return_type"] & ReturnType.STRONGEST) != 0]


def fuse_sweeps(sweeps: Sequence[Sweep]) -> Cloud:
    """One cloud from K sweeps of a still rig, one return per beam (docstring of the module)."""
    points = np.concatenate([_single_return(s) for s in sweeps])
    rpm = float(np.median([s.rpm for s in sweeps]))
    beams = max(int(round(360.0 / firing_step_deg(rpm))), 1)
    column = np.rint(points["azimuth"].astype(np.float64) * (beams / 360.0)).astype(np.int64) % beams
    key = points["ring"].astype(np.int64) * beams + column
    xyz = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(np.float64)
    rng = np.sqrt(np.einsum("ij,ij->i", xyz, xyz))
    order = np.lexsort((rng, key))
    key_sorted = key[order]
    starts = np.flatnonzero(np.r_[True, key_sorted[1:] != key_sorted[:-1]])
    counts = np.diff(np.r_[starts, len(key_sorted)])
    keep = counts >= (len(sweeps) + 1) // 2
    chosen = order[starts[keep] + (counts[keep] - 1) // 2]
    return Cloud(xyz[chosen], points["intensity"][chosen].astype(np.float32), points["ring"][chosen].astype(np.int16))
