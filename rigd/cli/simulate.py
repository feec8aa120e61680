"""``rigd simulate OUT``: write a dataset from the simulated rig (ground truth known)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from drivers.sim import SceneKind, head_sensor_height
from rigd.cli.args import non_negative_float, positive_int
from rigd.simulate import write_simulated_dataset


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "simulate",
        help="write a simulated dataset (box-world scenes, known ground truth)",
        description="Simulate a Ladybug5 panorama + VLP-16 sweep at PAIRS locations and write a dataset with "
        "its ground_truth.yaml (docs/simulator.md). Pair i of a seed is always the same.",
    )
    parser.add_argument("out", type=Path, metavar="OUT", help="new (or empty) dataset directory")
    parser.add_argument("--scene", choices=[k.value for k in SceneKind], default="indoor")
    parser.add_argument("--pairs", type=positive_int, default=12, help="number of locations (default 12)")
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (>= 0, default 0)")
    parser.add_argument("--width", type=positive_int, default=None,
                        help="panorama width px (default 1024); with --camera head each sensor's (default 512)")
    parser.add_argument("--height", type=positive_int, default=None,
                        help="panorama height px (default width/2); with --camera head each sensor's (default: the "
                        "Ladybug5's aspect, width x 2048/2448)")
    parser.add_argument("--noise-m", type=non_negative_float, default=0.02,
                        help="LiDAR range noise sigma in metres (default 0.02)")
    parser.add_argument("--sensor-effects", action="store_true",
                        help="what a real rig adds (docs/simulator.md): the Ladybug5's separate sensors stitched "
                        "(parallax of near objects, blended seams, per-sensor gain and falloff), JPEG images, "
                        "and the VLP-16's beam footprint (mixed returns at depth edges)")
    parser.add_argument("--dropouts", action="store_true",
                        help="energy-limited LiDAR returns: dark ground at grazing incidence drops out some tens "
                        "of metres ahead, at random near the limit (docs/simulator.md)")
    parser.add_argument("--trees", action="store_true",
                        help="outdoor scenes get rows of street trees: porous crowns of leaf clumps, which "
                        "crowd the LiDAR's rings with range jumps and the image with texture (docs/simulator.md)")
    parser.add_argument("--camera", choices=["panorama", "pinhole", "head"], default="panorama",
                        help="pinhole: a forward 1920x1200 camera (48 x 31 deg) below a level LiDAR, as on a car, "
                        "instead of the Ladybug5 panorama; head: the five side sensors of a Ladybug5 head as "
                        "separate 512x428 images, lying on their side as a Ladybug5's (docs/simulator.md)")
    parser.add_argument("--lidar", choices=["vlp16", "64"], default="vlp16",
                        help="64: a 64-ring street LiDAR (a dense band of 0.17 deg rings from +2 to -6 deg, like the "
                        "pinhole sample's) in place of the VLP-16 (docs/simulator.md)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    head = args.camera == "head"
    width = args.width if args.width is not None else (512 if head else 1024)
    height = args.height if args.height is not None else (head_sensor_height(width) if head else max(1, width // 2))
    out = write_simulated_dataset(args.out, args.scene, args.pairs, args.seed, width, height, args.noise_m,
                                  sensor_effects=args.sensor_effects, dropouts=args.dropouts, trees=args.trees,
                                  pinhole=args.camera == "pinhole", rings64=args.lidar == "64",
                                  head=head)
    effects = [text for on, text in ((args.sensor_effects, "sensor effects"), (args.dropouts, "LiDAR dropouts"),
                                     (args.trees, "street trees"), (args.lidar == "64", "a 64-ring LiDAR")) if on]
    extra = f" with {' and '.join(effects)}" if effects else ""
    sizes = {"pinhole": "1920x1200 pinhole", "head": f"5 sensors of {width}x{height}"}
    size = sizes.get(args.camera, f"{width}x{height}")
    print(f"wrote {args.pairs} simulated {args.scene} pairs ({size}){extra} to {out}")
    return 0
