"""``rigd evaluate initial DATASET``: the global search for an initial guess from random mounts."""

from __future__ import annotations

import argparse
from typing import Any

from rigd.cli.args import (
    add_evaluation_options,
    evaluation_settings,
    non_negative_float,
    positive_int,
)
from rigd.evaluate.initial import InitialRequest, run_initial


def register_initial(protocols: Any) -> None:
    """The ``initial`` protocol of ``rigd evaluate`` (registered by rigd.cli.evaluate)."""
    parser = protocols.add_parser(
        "initial", help="calibrate with no initial guess from random mounts (the global search)",
        description="Mounts the camera at random (yaw within +-YAW_DEG, roll and pitch within +-TILT_DEG, lever arm "
        "within +-LEVER_M per axis) by re-expressing the dataset's clouds, calibrates each with no initial guess, "
        "and counts the runs that end as close to their mount as a run started 5 deg / 10 cm from the ground truth "
        "(within 0.2 deg / 2 cm). Writes OUT/initial.yaml.")
    add_evaluation_options(parser)
    parser.add_argument("--trials", type=positive_int, default=100, help="number of random mounts (default 100)")
    parser.add_argument("--yaw-deg", type=non_negative_float, default=180.0, help="yaw range, +- deg (default 180)")
    parser.add_argument("--tilt-deg", type=non_negative_float, default=30.0,
                        help="roll and pitch range, +- deg (default 30)")
    parser.add_argument("--lever-m", type=non_negative_float, default=0.3,
                        help="lever-arm range per axis, +- m (default 0.3)")
    parser.set_defaults(func=run_initial_command)


def run_initial_command(args: argparse.Namespace) -> int:
    settings = evaluation_settings(args)
    rep = run_initial(InitialRequest(settings, args.trials, args.yaw_deg, args.tilt_deg, args.lever_m))
    ref = rep["reference"]
    print(f"initial guess on {rep['dataset']} ({rep['pairs']} pairs): {rep['settings']['trials']} random mounts "
          f"(yaw +-{args.yaw_deg:g}, roll/pitch +-{args.tilt_deg:g} deg, lever arm +-{args.lever_m:g} m), no guess")
    print(f"  reference run (start 5 deg / 10 cm off): {ref['rotation_err_deg']:.3f} deg, "
          f"{ref['translation_err_cm']:.2f} cm")
    print(f"  as close as the reference (+0.2 deg / +2 cm): {rep['success']}/{rep['settings']['trials']} "
          f"({rep['success_rate'] * 100:.0f} %)")
    print(f"  search time: median {rep['median_search_s']:.1f} s, max {rep['max_search_s']:.1f} s; whole run median "
          f"{rep['median_total_s']:.1f} s; {rep['wall_time_s']:.0f} s wall")
    if rep["verdicts"]:
        print(f"  verdicts: {rep['verdicts']}; trusted but not as close as the reference: {rep['trusted_but_wrong']}")
    return 0
