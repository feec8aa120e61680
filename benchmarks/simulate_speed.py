"""Time of ``rigd simulate`` (target: 12 pairs at 1024x512 in under 60 s) and where it goes.

Run: .venv/bin/python benchmarks/simulate_speed.py [--pairs 12] [--width 1024] [--seed 3]
Prints, per scene kind, the wall time of writing a whole dataset, then for the first pair the split
between scene generation, the panorama render (camera + shadow rays) and the LiDAR sweep.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from drivers.sim import SimConfig, make_scene, render_panorama, scan
from drivers.sim.rig import PAPER_T_CAMERA_LIDAR, place_rig, rng_for, scene_kind
from rigd.simulate import write_simulated_dataset


def _split(kind: str, seed: int, width: int) -> str:
    k = scene_kind(kind)
    start = time.perf_counter()
    scene = make_scene(k, seed, 0)
    pose = place_rig(scene, rng_for(k, seed, 0, "pose"), PAPER_T_CAMERA_LIDAR)
    t_scene = time.perf_counter()
    render_panorama(scene, pose, width, width // 2, np.random.default_rng(0))
    t_image = time.perf_counter()
    scan(scene, pose.compose(SimConfig().T_camera_lidar), np.random.default_rng(0))
    t_lidar = time.perf_counter()
    return (f"scene {t_scene - start:.2f} s ({scene.n_boxes} boxes, {len(scene.paint_box)} paints, "
            f"{len(scene.recess_box)} recesses), panorama {t_image - t_scene:.2f} s, sweep {t_lidar - t_image:.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=12)
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    for kind in ("indoor", "outdoor"):
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            write_simulated_dataset(Path(tmp) / "ds", kind, args.pairs, args.seed, args.width, args.width // 2,
                                    progress=False)
            total = time.perf_counter() - start
        print(f"{kind}: {args.pairs} pairs at {args.width}x{args.width // 2} in {total:.1f} s "
              f"({total / args.pairs:.2f} s a pair)")
        print(f"  pair 0: {_split(kind, args.seed, args.width)}")


if __name__ == "__main__":
    main()
