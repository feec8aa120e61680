"""``rigd dataset thin DATASET OUT``: a dataset whose clouds are those of a sparser LiDAR (docs/dataset.md,
"Thinning")."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from rigd.cli.args import non_negative_float, positive_float, progress_bar


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
    return value


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("dataset", help="derive a dataset from another",
                                   description="Derive a new dataset from an existing one (docs/dataset.md).")
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    thin = actions.add_parser(
        "thin", help="keep the rings nearest a grid of elevations: a sparser LiDAR from a denser one",
        description="Write OUT: DATASET with every pair's cloud reduced to the rings whose elevation (median over "
        "the dataset) is nearest each of PHASE + k x SPACING deg, within half a spacing, and optionally fewer "
        "points along each ring. Images, masks, rig, reference and ground truth are kept as they are; each "
        "pair's meta.yaml records what was kept. The clouds must carry rings (rigd import writes them). The grid "
        "cannot reach beyond the source's elevations: an HDL-64E covers +2 to -25 deg, a VLP-16 +-15 deg.")
    thin.add_argument("src", type=Path, metavar="DATASET", help="the dataset to thin")
    thin.add_argument("out", type=Path, metavar="OUT", help="new (or empty) dataset folder, not inside DATASET; "
                      "written beside it and renamed into place when complete")
    thin.add_argument("--overwrite", action="store_true", help="replace OUT as a whole when it holds anything")
    thin.add_argument("--ring-spacing-deg", type=positive_float, default=2.0, metavar="DEG",
                      help="elevation between kept rings (default 2: a VLP-16)")
    thin.add_argument("--phase-deg", type=_finite, default=0.0, metavar="DEG",
                      help="where the grid lies: rings nearest PHASE + k x SPACING (default 0)")
    thin.add_argument("--azimuth-step-deg", type=non_negative_float, default=0.0, metavar="DEG",
                      help="along a ring, drop points nearer than this in azimuth to the last one kept, e.g. 0.2 "
                      "for a VLP-16 at 600 rpm (default 0: keep every point)")
    thin.add_argument("--rings-by", choices=("dataset", "pair"), default="dataset",
                      help="pick rings by each ring's median elevation over the dataset, the same lasers in every "
                      "pair as a real sparser LiDAR has (default), or by each pair's own medians")
    thin.set_defaults(func=_thin)


def _thin(args: argparse.Namespace) -> int:
    from rigd.dataset.thin import RingsBy, ThinOptions, thin_dataset

    options = ThinOptions(args.ring_spacing_deg, args.phase_deg, args.azimuth_step_deg, RingsBy(args.rings_by))
    bar, progress = progress_bar("thin", "pair")
    with bar:
        summary = thin_dataset(args.src, args.out, options, progress, overwrite=args.overwrite)
    rings = ", ".join(f"{e:+.2f}" for e in summary.choice.elevations_deg)
    print(f"written: {summary.out} ({summary.pairs} pairs; {len(summary.choice.source_rings)} rings kept at "
          f"{rings} deg; {summary.points_kept} of {summary.points_source} points, "
          f"{100 * summary.points_kept / max(summary.points_source, 1):.1f} %)")
    return 0
