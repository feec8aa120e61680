"""Figures of the evaluation protocols: paper Fig. 19 (convergence) and Fig. 11 (precision box plots)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from numpy.typing import NDArray

from calib.evaluate import RunStats

F64 = NDArray[np.float64]

# Panel title, unit and the factor from calib.evaluate's units (deg, m) to the plotted unit.
_PANELS = (("(a) roll", "deg", 1.0), ("(b) pitch", "deg", 1.0), ("(c) yaw", "deg", 1.0),
           ("(d) t_x", "cm", 100.0), ("(e) t_y", "cm", 100.0), ("(f) t_z", "cm", 100.0))


def _figure() -> tuple[Figure, list[Axes]]:
    fig = Figure(figsize=(13, 7), layout="constrained")
    FigureCanvasAgg(fig)  # no pyplot: no global backend or figure registry in a library
    return fig, list(fig.subplots(2, 3).ravel())


def plot_convergence(path: Path, starts: F64, stats: RunStats, reference: F64, reference_label: str) -> None:
    """Fig. 19: per parameter, the start (green square) and result of each trial (black circle when converged,
    red triangle when not; drawn at the axis edge when beyond it) and the reference line.

    ``starts`` (N,6) and ``reference`` (6,): roll, pitch, yaw deg and x, y, z m, as ``stats.values``.
    """
    fig, axes = _figure()
    trial = np.arange(1, len(starts) + 1)
    good = stats.converged
    bad = ~good & np.isfinite(stats.values[:, 0])
    for k, (ax, (title, unit, scale)) in enumerate(zip(axes, _PANELS, strict=True)):
        start, result, ref = starts[:, k] * scale, stats.values[:, k] * scale, reference[k] * scale
        shown = np.concatenate([start, result[good], [ref]])
        pad = 0.05 * max(float(np.ptp(shown)), 1e-6)
        lo, hi = float(shown.min()) - pad, float(shown.max()) + pad
        ax.plot(trial, start, "s", color="tab:green", ms=3, label="initial guess")
        ax.plot(trial[good], result[good], "o", color="black", ms=3, mfc="none",
                label="converged")
        ax.plot(trial[bad], np.clip(result[bad], lo, hi), "^", color="red", ms=4,
                label="not converged")
        ax.axhline(ref, color="tab:blue", lw=1, label=reference_label)
        ax.set(title=title, xlabel="trial", ylabel=unit, ylim=(lo, hi))
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=4)
    fig.suptitle(f"Convergence: {stats.converged_count}/{stats.runs} runs converged ({stats.converged_percent:.1f} %)")
    fig.savefig(path, dpi=110)


def plot_precision(path: Path, stats: RunStats) -> None:
    """Fig. 11: per parameter, a box plot of the finished runs' deviation from their mean (box Q1-Q3, red
    median, whiskers at 1.5 IQR, red x beyond)."""
    fig, axes = _figure()
    done = stats.values[np.isfinite(stats.values[:, 0])]
    deviation = done - done.mean(axis=0) if len(done) else done
    for k, (ax, (title, unit, scale)) in enumerate(zip(axes, _PANELS, strict=True)):
        ax.boxplot(deviation[:, k] * scale, whis=1.5, medianprops={"color": "red"},
                   flierprops={"marker": "x", "markeredgecolor": "red"})
        ax.set(title=title, ylabel=f"deviation from the mean ({unit})", xticks=[])
    fig.suptitle(f"Precision: {len(done)} finished runs of {stats.runs}")
    fig.savefig(path, dpi=110)
