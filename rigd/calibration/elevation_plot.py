"""The picture of a fitted LiDAR elevation offset: the finest level's cost over the offsets tried (calib.elevation)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.elevation import FIT_SPAN_DEG, ElevationFit


def plot_elevation_profile(path: Path, fit: ElevationFit, declared_deg: float = 0.0) -> None:
    """The profile's costs (points), the parabola the offset is read from (line), the offset and its σ band;
    offsets as rig.yaml would declare them (``declared_deg`` plus the grid's)."""
    # Imported here: matplotlib is a third of an image-free calibration's start-up and 40 MB of its peak memory.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4.6), layout="constrained")
    FigureCanvasAgg(fig)  # no pyplot: no global backend or figure registry in a library
    ax = fig.subplots()
    grid, costs = np.asarray(fit.grid_deg) + declared_deg, np.asarray(fit.costs)
    offset = declared_deg + fit.offset_deg
    ax.axvspan(offset - fit.sigma_deg, offset + fit.sigma_deg, color="tab:blue", alpha=0.15, label="±1σ")
    near = np.abs(grid - grid[np.argmin(costs)]) <= FIT_SPAN_DEG + 1e-9
    if near.sum() >= 3:
        x = np.linspace(grid[near].min(), grid[near].max(), 100)
        ax.plot(x, np.polyval(np.polyfit(grid[near], costs[near], 2), x), color="tab:blue", lw=1, label="parabola")
    ax.plot(grid, costs, "o", color="black", ms=4, label="cost after refining the pose")
    ax.axvline(offset, color="tab:blue", lw=1.5, label=f"offset {offset:+.3f}° ± {fit.sigma_deg:.3f}°")
    ax.set(xlabel="LiDAR elevation offset (deg): every point raised by it", ylabel="finest level's cost (lower fits)",
           title="LiDAR elevation offset" + ("  (at the end of the range tried)" if fit.at_bound else ""))
    fig.legend(loc="outside lower center", ncols=2, fontsize="small")
    fig.savefig(path, dpi=110)
