"""A sparser LiDAR from a denser one (``rigd dataset thin``, docs/dataset.md#thinning): every pair's cloud keeps
the rings nearest a grid of elevations, and optionally fewer points along each ring.

This is how rigd is measured at its own LiDAR's density (a VLP-16: 16 rings 2° apart, a point every 0.2° of
azimuth at 600 rpm) on real recordings of a denser one (an HDL-64E: 64 rings 0.3–0.5° apart). By default the same
lasers are kept in every pair, as a real sparser LiDAR has them: a ring's elevation is the median over the
dataset; ``RingsBy.PAIR`` picks each pair's rings by that pair's own medians (two near-identical thinnings, to
see how much a calibration depends on which rings a pair happens to keep).
The grid cannot reach beyond the source's own elevations (an HDL-64E covers +2° to −25°, a VLP-16 ±15°).
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rigd.dataset.pcd import Cloud, read_pcd
from rigd.dataset.records import SINGLE_VIEW
from rigd.dataset.store import open_dataset, read_yaml_mapping, write_pair, write_yaml
from rigd.errors import DatasetError
from rigd.outdir import claim_output_dir, write_error

COPIED = ("reference.yaml", "ground_truth.yaml", "masks")  # what the thinned dataset shares with its source
MIN_RING_POINTS = 10  # a ring with fewer points in a pair gives that pair no elevation for it
MIN_AZIMUTH_STEP_DEG = 1e-3  # a VLP-16 resolves 0.1 deg, an HDL-64E 0.08 deg; finer keeps every point


class RingsBy(Enum):
    """Whose ring elevations the grid picks rings by."""

    DATASET = "dataset"  # each ring's median over the dataset: the same lasers in every pair
    PAIR = "pair"  # each pair's own medians


@dataclass(frozen=True)
class ThinOptions:
    """``ring_spacing_deg`` > 0 between kept rings; the grid is ``phase_deg`` + k ``ring_spacing_deg``;
    ``azimuth_step_deg`` >= 0: along a ring, a point nearer than this in azimuth to the last one kept is dropped
    (0: every point kept); ``rings_by``: the elevations the rings are picked by."""

    ring_spacing_deg: float
    phase_deg: float = 0.0
    azimuth_step_deg: float = 0.0
    rings_by: RingsBy = RingsBy.DATASET

    def __post_init__(self) -> None:
        if not (math.isfinite(self.ring_spacing_deg) and self.ring_spacing_deg > 0):
            raise DatasetError(f"the ring spacing must be a positive number of degrees, got {self.ring_spacing_deg}")
        if not math.isfinite(self.phase_deg):
            raise DatasetError(f"the grid's phase must be a number of degrees, got {self.phase_deg}")
        if not (math.isfinite(self.azimuth_step_deg) and 0 <= self.azimuth_step_deg < 90):
            raise DatasetError(f"the azimuth step must be 0 to 90 degrees, got {self.azimuth_step_deg}")
        if 0 < self.azimuth_step_deg < MIN_AZIMUTH_STEP_DEG:
            raise DatasetError(f"the azimuth step {self.azimuth_step_deg:g} deg is finer than any LiDAR resolves "
                               f"(at least {MIN_AZIMUTH_STEP_DEG:g} deg, or 0 to keep every point)")


@dataclass(frozen=True)
class RingChoice:
    """The source rings kept (``source_rings``, lowest first; they become rings 0, 1, ...), their elevations
    ``elevations_deg`` (median over the dataset) and the grid elevation each was kept for (``grid_deg``)."""

    source_rings: tuple[int, ...]
    elevations_deg: tuple[float, ...]
    grid_deg: tuple[float, ...]


def ring_elevations_deg(cloud: Cloud) -> dict[int, float]:
    """Each ring's median elevation, deg, in one cloud (rings with fewer than MIN_RING_POINTS points left out)."""
    if cloud.ring is None:
        raise DatasetError("the cloud has no ring field")
    xyz = cloud.points_lidar
    elevation = np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))
    rings, inverse, counts = np.unique(cloud.ring, return_inverse=True, return_counts=True)
    return {int(r): float(np.median(elevation[inverse == k])) for k, r in enumerate(rings)
            if counts[k] >= MIN_RING_POINTS}


def choose_rings(elevations_deg: Mapping[int, float], options: ThinOptions) -> RingChoice:
    """For every grid elevation within the source's range, the ring nearest it, if within half a spacing."""
    if not elevations_deg:
        raise DatasetError("no ring has enough points to place it")
    rings = np.array(list(elevations_deg), dtype=np.int64)
    elev = np.array([elevations_deg[r] for r in rings], dtype=np.float64)
    step, half = options.ring_spacing_deg, options.ring_spacing_deg / 2
    k = np.arange(math.ceil((elev.min() - half - options.phase_deg) / step),
                  math.floor((elev.max() + half - options.phase_deg) / step) + 1)
    chosen: dict[int, float] = {}
    for grid in options.phase_deg + k * step:
        nearest = int(np.argmin(np.abs(elev - grid)))
        if abs(elev[nearest] - grid) <= half and int(rings[nearest]) not in chosen:
            chosen[int(rings[nearest])] = float(grid)
    order = sorted(chosen, key=lambda r: elevations_deg[r])
    return RingChoice(tuple(order), tuple(round(elevations_deg[r], 4) for r in order),
                      tuple(round(chosen[r], 4) for r in order))


def _azimuth_kept(azimuth_deg: NDArray[np.float64], step_deg: float) -> NDArray[np.int64]:
    """Indices into one ring's ``azimuth_deg`` (N,) in [0, 360): walking round the ring, each point at least
    ``step_deg`` after the last one kept (and before the first one again)."""
    order = np.argsort(azimuth_deg, kind="stable")
    ordered = azimuth_deg[order]
    kept = [0]
    # The next index is always past the last one kept, even where ``+ step_deg`` is lost to rounding.
    while (nxt := max(int(np.searchsorted(ordered, ordered[kept[-1]] + step_deg)), kept[-1] + 1)) < len(ordered):
        kept.append(nxt)
    while len(kept) > 1 and ordered[kept[-1]] > ordered[0] + 360.0 - step_deg:
        kept.pop()
    return np.sort(order[kept])


def thin_cloud(cloud: Cloud, choice: RingChoice, azimuth_step_deg: float = 0.0) -> Cloud:
    """``cloud`` with only ``choice``'s rings (renumbered 0, 1, ... lowest first), in their recorded order, each
    with at least ``azimuth_step_deg`` between its points."""
    if cloud.ring is None:
        raise DatasetError("the cloud has no ring field")
    keep: list[NDArray[np.int64]] = []
    new_ring: list[NDArray[np.int16]] = []
    for new, source in enumerate(choice.source_rings):
        index = np.flatnonzero(cloud.ring == source)
        if azimuth_step_deg > 0 and index.size:
            xyz = cloud.points_lidar[index]
            index = index[_azimuth_kept(np.mod(np.degrees(np.arctan2(xyz[:, 1], xyz[:, 0])), 360.0),
                                        azimuth_step_deg)]
        keep.append(index)
        new_ring.append(np.full(index.size, new, dtype=np.int16))
    order = np.argsort(np.concatenate(keep), kind="stable")  # the recorded order, which scan-order rings rely on
    index = np.concatenate(keep)[order]
    intensity = None if cloud.intensity is None else cloud.intensity[index]
    return Cloud(cloud.points_lidar[index], intensity, np.concatenate(new_ring)[order])


def _record(source: Path, options: ThinOptions, choice: RingChoice) -> dict[str, Any]:
    """What a pair's meta.yaml records of its thinning."""
    return {"source": str(source), "ring_spacing_deg": options.ring_spacing_deg, "phase_deg": options.phase_deg,
            "azimuth_step_deg": options.azimuth_step_deg, "rings_by": options.rings_by.value,
            "source_rings": list(choice.source_rings), "elevations_deg": list(choice.elevations_deg),
            "grid_deg": list(choice.grid_deg)}


@dataclass(frozen=True)
class ThinSummary:
    """What ``thin_dataset`` wrote: ``pairs`` to ``out``, the rings kept, and points kept of the source's."""

    out: Path
    pairs: int
    choice: RingChoice
    points_kept: int
    points_source: int


def _dataset_elevations(source: Path, pair_dirs: tuple[Path, ...]) -> dict[int, float]:
    """Each ring's median over the pairs of its per-pair median elevation."""
    per_ring: dict[int, list[float]] = {}
    for folder in pair_dirs:
        cloud = read_pcd(folder / "cloud.pcd")
        if cloud.ring is None:
            raise DatasetError(f"{folder / 'cloud.pcd'}: no ring field: thinning keeps whole rings (rigd import "
                               "recovers rings from a recording's scan order)")
        for ring, elevation in ring_elevations_deg(cloud).items():
            per_ring.setdefault(ring, []).append(elevation)
    return {ring: float(np.median(values)) for ring, values in per_ring.items()}


def _prepare_out(source: Path, out: Path, lidar_note: str) -> None:
    """``out`` (a new folder) with the source's rig.yaml (its LiDAR model noted) and shared files."""
    rig = read_yaml_mapping(source / "rig.yaml")
    lidar: dict[str, Any] = rig["lidar"] if isinstance(rig.get("lidar"), dict) else {}
    rig["lidar"] = {**lidar, "model": f"{lidar.get('model', 'VLP-16')} ({lidar_note})"}
    write_yaml(out / "rig.yaml", rig)
    try:
        for name in COPIED:
            if (source / name).is_dir():
                shutil.copytree(source / name, out / name)
            elif (source / name).is_file():
                shutil.copyfile(source / name, out / name)
    except OSError as exc:
        raise write_error(out / name, exc) from exc


def thin_dataset(source: Path, out: Path, options: ThinOptions,
                 progress: Callable[[int, int], None] | None = None, *, overwrite: bool = False) -> ThinSummary:
    """Write ``out``: ``source`` with every pair's cloud thinned by ``options`` (images, masks, rig, reference and
    ground truth as they are); each pair's meta.yaml records what was kept under ``thinned``. ``progress(done,
    total)`` after each pair. ``out`` must be new or empty (``overwrite``: replaced as a whole), and neither the
    source nor inside it; it appears complete or not at all (rigd.outdir)."""
    source, out = Path(source), Path(out)
    dataset = open_dataset(source)
    if not len(dataset):
        raise DatasetError(f"{source}: no pairs to thin")
    by_dataset = options.rings_by is RingsBy.DATASET
    choice = choose_rings(_dataset_elevations(source, dataset.pair_dirs), options)
    note = (f"{len(choice.source_rings)} rings {options.ring_spacing_deg:g} deg apart, "
            f"{'' if by_dataset else 'picked per pair, '}thinned by rigd")
    kept = total = 0
    with claim_output_dir(out, inputs=[source], overwrite=overwrite) as folder:
        _prepare_out(source, folder, note)
        for i, pair_dir in enumerate(dataset.pair_dirs):
            cloud = read_pcd(pair_dir / "cloud.pcd")
            mine = choice if by_dataset else choose_rings(ring_elevations_deg(cloud), options)
            thinned = thin_cloud(cloud, mine, options.azimuth_step_deg)
            meta = read_yaml_mapping(pair_dir / "meta.yaml") if (pair_dir / "meta.yaml").is_file() else {}
            meta["thinned"] = {**_record(source, options, mine), "points": len(thinned), "points_source": len(cloud)}
            images = {view: dataset.image_path(i, view) for view in dataset.views}
            single = dataset.views == (SINGLE_VIEW,)
            write_pair(folder, int(pair_dir.name), images[SINGLE_VIEW] if single else images, thinned, meta)
            kept, total = kept + len(thinned), total + len(cloud)
            if progress is not None:
                progress(i + 1, len(dataset))
    return ThinSummary(out, len(dataset), choice, kept, total)
