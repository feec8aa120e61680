"""``rigd evaluate compare DATASET --methods gmm,mi,nid,gom,...``: Table 1 and Fig. 19 for several methods."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from calib.evaluate import StartAxes
from rigd.cli.args import add_start_axes_option, non_negative_float, positive_int
from rigd.evaluate.compare import CompareRequest, parse_methods, run_compare


def register_compare(protocols: Any) -> None:
    """The ``compare`` protocol of ``rigd evaluate`` (registered by rigd.cli.evaluate)."""
    p = protocols.add_parser(
        "compare", help="the paper's comparison: precision and convergence of several methods side by side",
        description="For each method: SUBSETS random subsets of SIZE pairs calibrated from the reference (Table 1; "
        "skipped when the dataset has no more than SIZE pairs) and TRIALS random starts around it (Fig. 19). "
        "The reference is ground_truth.yaml (else reference.yaml, else rig.yaml's initial_guess). Writes "
        "OUT/compare.yaml, "
        "compare.md (the table) and compare.png.")
    p.add_argument("dataset", metavar="DATASET")
    p.add_argument("--methods", default="gmm,mi,nid,gom",
                   help="comma-separated: gmm (= rigd), paper, mi, nid, gom, rigd+nid, gmm-w1, gmm-uniform, "
                   "gmm-paper-edges, gmm-paper-schedule (default gmm,mi,nid,gom)")
    p.add_argument("--subsets", type=positive_int, default=10, help="precision subsets (default 10)")
    p.add_argument("--size", type=positive_int, default=12, help="pairs per subset (default 12)")
    p.add_argument("--trials", type=positive_int, default=10, help="convergence starts (default 10)")
    p.add_argument("--rot-deg", type=non_negative_float, default=5.0, help="start range, deg (default 5)")
    p.add_argument("--trans-m", type=non_negative_float, default=0.1, help="start range, m (default 0.1)")
    add_start_axes_option(p)
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--workers", type=positive_int, default=2, help="parallel processes (default 2)")
    p.add_argument("--out", default=None, help="output directory (default DATASET/evaluation)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an earlier compare's report, table and plot there (default: refused)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    request = CompareRequest(Path(args.dataset), parse_methods(args.methods), args.subsets, args.size, args.trials,
                             args.rot_deg, args.trans_m, args.seed, args.workers,
                             Path(args.out) if args.out else None, start_axes=StartAxes(args.start_axes),
                             overwrite=args.overwrite)
    outcome = run_compare(request)
    rep = outcome.report
    s = rep["settings"]
    print(f"compare on {rep['dataset']} ({rep['pairs_in_dataset']} pairs) against the "
          f"{rep['reference']['source'].replace('_', ' ')}: {s['subsets']} subsets of {s['size']}, {s['trials']} "
          f"starts within +-{s['rot_deg']} deg / +-{s['trans_m'] * 100:g} cm, seed {s['seed']}")
    print(outcome.table)
    print(f"time: {rep['wall_time_s']:.0f} s wall; written: {outcome.yaml_path}, {outcome.plot_path}")
    return 0
