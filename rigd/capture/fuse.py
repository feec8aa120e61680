"""Fusing K sweeps of a still rig into one cloud: per beam, the return with the median range.

A beam is a (ring, firing azimuth) cell one firing step wide (0.2 degrees at 600 rpm), centred on the
firing sequence's azimuth: a laser's own azimuth is later by its delay in the sequence (laser k fires
k * 2.304 us after laser 0, up to 0.12 degrees), which is taken off so that every ring of one firing lands
in the same cell. A still rig's beams repeat from turn to turn within that step (the head's phase drifts
between turns unless phase-locked). Per beam the
return whose range is the median of the K turns' is kept whole (its point, intensity and ring), so no
point is invented between a foreground and a background surface: a beam on a depth edge keeps one of its
real returns. The median of K ranges has about 1.25 / sqrt(K) of one return's noise for Gaussian noise.
A beam that returned in fewer than half the turns (a grazing or dark surface, a depth edge) is dropped.

Which sweeps a pair fuses (:func:`sweeps_for_frame`, shared by ``rigd capture`` and ``rigd import bag``): those
lying wholly inside the still window, the ``count`` whose middles are nearest the frame's time, in time order.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from drivers.vlp16 import ReturnMode, ReturnType, Sweep
from drivers.vlp16.layout import FIRING_US, NOMINAL_ELEVATION_DEG, SEQUENCE_US
from rigd.dataset import Cloud

LASER_OF_RING = np.argsort(NOMINAL_ELEVATION_DEG)  # (16,) firing order of each ring (0 = lowest beam)


def firing_step_deg(rpm: float) -> float:
    """Azimuth advance between two firing sequences (55.296 us) at ``rpm``, degrees."""
    return rpm / 60.0 * 360.0 * SEQUENCE_US * 1e-6


def sweeps_for_frame(spans: Sequence[tuple[float, float]], frame_t: float, window: tuple[float, float],
                     count: int) -> list[int]:
    """Indices into ``spans`` ((start, end) s of each sweep) of the sweeps a pair with the frame at ``frame_t`` s
    fuses: inside ``window`` (start, end) s, the ``count`` with their middles nearest ``frame_t``, by start time."""
    inside = [i for i, (start, end) in enumerate(spans) if start >= window[0] and end <= window[1]]
    nearest = sorted(inside, key=lambda i: abs(0.5 * (spans[i][0] + spans[i][1]) - frame_t))
    return sorted(nearest[:count], key=lambda i: spans[i][0])


def _single_return(sweep: Sweep) -> np.ndarray:
    """The sweep's points with one return per beam: the strongest of a dual-return stream."""
    if sweep.return_mode is not ReturnMode.DUAL:
        return sweep.points
    strongest: np.ndarray = sweep.points[(sweep.points["return_type"] & ReturnType.STRONGEST) != 0]
    return strongest


def fuse_sweeps(sweeps: Sequence[Sweep]) -> Cloud:
    """One cloud from K sweeps of a still rig, one return per beam (docstring of the module)."""
    points = np.concatenate([_single_return(s) for s in sweeps])
    rpm = float(np.median([s.rpm for s in sweeps]))
    beams = max(int(round(360.0 / firing_step_deg(rpm))), 1)
    laser_delay_deg = LASER_OF_RING * FIRING_US * 1e-6 * rpm / 60.0 * 360.0
    firing_azimuth = points["azimuth"].astype(np.float64) - laser_delay_deg[points["ring"]]
    column = np.rint(firing_azimuth * (beams / 360.0)).astype(np.int64) % beams
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
