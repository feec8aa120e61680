"""How often the stillness gate rejects a rig that vibrates or creeps, and how soon it accepts a still one.

Targets (issue 35): +-0.1 deg vibration or 0.5 cm/s creep rejected in >= 95 % of stops; a truly still rig
accepted within 2 s. Each stop is a place in a simulated scene (indoor and outdoor in turn, a new seed each),
held for ``--seconds``, with the rig's motion from drivers.sim.disturbance (a new axis, direction and phase
per stop). Its VLP-16 sweeps (one every 0.0995 s, scanned at the pose of mid-turn, as the simulated rig
streams them) go through rigd.capture.gate.StillnessGate with the thresholds capture uses
(StillThresholds.from_tolerance(0.2)). A stop is accepted when the gate holds a still window of
``--still-seconds`` and ``--sweeps`` sweeps (rigd capture's defaults), rejected when it never does.

With ``--camera`` it also measures the camera test: the largest sector shift between two renders of one
place (noise), and after a 0.1 / 0.2 deg turn and a 1 cm move, at 1024x512.

``--margin`` runs smaller motions instead (half and a third of the vibration, 40 % and 20 % of the creep).

Run: .venv/bin/python benchmarks/stillness_gate.py [--stops 20] [--seconds 8] [--camera] [--margin]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

import numpy as np

from drivers.sim import Pose, make_scene, render_panorama, scan
from drivers.sim.disturbance import Disturbance, axis_angle_matrix
from drivers.sim.rig import PAPER_T_CAMERA_LIDAR, place_rig, rng_for, scene_kind
from drivers.sim.scene import Scene
from drivers.sim.stream import TURN_S
from rigd.capture.gate import (
    StillnessGate,
    StillThresholds,
    SweepSample,
    camera_image,
    camera_shift_deg,
    direction_grid,
)

CONDITIONS = {
    "still": Disturbance(),
    "vibration +-0.1 deg, 2 Hz": Disturbance(vibration_deg=0.1, vibration_hz=2.0),
    "vibration +-0.1 deg, 0.5 Hz": Disturbance(vibration_deg=0.1, vibration_hz=0.5),
    "creep 0.5 cm/s": Disturbance(creep_m_s=0.005),
    "creep 0.1 deg/s (yaw)": Disturbance(creep_deg_s=0.1),
}
MARGIN = {  # --margin: how far below the targets the gate still sees motion
    "vibration +-0.05 deg, 2 Hz": Disturbance(vibration_deg=0.05, vibration_hz=2.0),
    "vibration +-0.03 deg, 2 Hz": Disturbance(vibration_deg=0.03, vibration_hz=2.0),
    "creep 0.2 cm/s": Disturbance(creep_m_s=0.002),
    "creep 0.1 cm/s": Disturbance(creep_m_s=0.001),
}


@dataclass(frozen=True)
class StopResult:
    """One stop: seconds from its first sweep until the gate held a still window (None: never), and the
    largest rotation deg and translation m the gate measured from a window's first sweep."""

    accepted_after_s: float | None
    max_rotation_deg: float
    max_translation_m: float


def place(stop: int) -> tuple[Scene, Pose]:
    kind = scene_kind("indoor" if stop % 2 == 0 else "outdoor")
    scene = make_scene(kind, stop, 0)
    return scene, place_rig(scene, rng_for(kind, stop, 0, "pose"), PAPER_T_CAMERA_LIDAR)


def run_stop(stop: int, disturbance: Disturbance, seconds: float, still_seconds: float, sweeps: int) -> StopResult:
    scene, pose = place(stop)
    gate = StillnessGate(StillThresholds.from_tolerance(0.2))
    start = 50.0 + 7.3 * stop  # some way into the disturbance's life, a different phase per stop
    largest = [0.0, 0.0]
    for turn in range(int(seconds / TURN_S)):
        t = start + turn * TURN_S
        pose_lidar = disturbance.apply(pose, t + TURN_S / 2).compose(PAPER_T_CAMERA_LIDAR)
        sweep = scan(scene, pose_lidar, np.random.default_rng([stop, turn]))
        grid = direction_grid(sweep.points_lidar, sweep.ring)
        motion = gate.add_sweep(SweepSample(t, t + TURN_S, grid.range_m, grid))
        if motion is not None:
            largest = [max(largest[0], motion.rotation_deg), max(largest[1], motion.translation_m)]
        if gate.held(still_seconds, sweeps):
            return StopResult(t + TURN_S - start, *largest)
    return StopResult(None, *largest)


def report(name: str, results: list[StopResult], still_seconds: float) -> str:
    accepted = [r.accepted_after_s for r in results if r.accepted_after_s is not None]
    rotation = np.array([r.max_rotation_deg for r in results])
    translation = np.array([r.max_translation_m for r in results]) * 1000
    line = (f"{name:30s} {len(results)} stops: rejected {100 * (1 - len(accepted) / len(results)):5.1f} %, "
            f"accepted {len(accepted)}")
    if accepted:
        line += (f" after {min(accepted):.2f}-{max(accepted):.2f} s (within {still_seconds + TURN_S:.1f} s: "
                 f"{sum(a <= still_seconds + TURN_S + 1e-9 for a in accepted)})")
    return line + (f"; largest motion from a window's first sweep: {np.median(rotation):.3f} deg median "
                   f"({rotation.min():.3f}-{rotation.max():.3f}), {np.median(translation):.2f} mm median "
                   f"({translation.min():.2f}-{translation.max():.2f})")


def camera_figures(stops: int) -> None:
    """The camera test's noise and response on 1024x512 renders (2 s each on a 2-core machine)."""
    cases = {"still (noise)": (0.0, 0.0), "turn 0.1 deg": (0.1, 0.0), "turn 0.2 deg": (0.2, 0.0),
             "move 1 cm": (0.0, 0.01)}
    found: dict[str, list[float]] = {name: [] for name in cases}
    for stop in range(stops):
        scene, pose = place(stop)
        first = camera_image(render_panorama(scene, pose, 1024, 512, np.random.default_rng([stop, 0])))
        axis = np.random.default_rng(stop).normal(size=3)
        axis /= np.linalg.norm(axis)
        for k, (name, (turn_deg, move_m)) in enumerate(cases.items()):
            moved = Pose(pose.rotation @ axis_angle_matrix(axis, np.radians(turn_deg)),
                         pose.translation_m + move_m * np.array([axis[0], axis[1], 0.0]))
            image = render_panorama(scene, moved, 1024, 512, np.random.default_rng([stop, k + 1]))
            found[name].append(camera_shift_deg(first, camera_image(image)))
    threshold = StillThresholds.from_tolerance(0.2).camera_threshold_deg(1024)
    print(f"camera (1024x512, threshold {threshold:.3f} deg), largest sector shift over {stops} places:")
    for name, values in found.items():
        print(f"  {name:14s} {np.min(values):.3f}-{np.max(values):.3f} deg, above the threshold: "
              f"{sum(v > threshold for v in values)}/{len(values)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stops", type=int, default=20)
    parser.add_argument("--seconds", type=float, default=8.0, help="how long each stop lasts (rigd capture's "
                        "simulated rig stands still_seconds + 6 s)")
    parser.add_argument("--still-seconds", type=float, default=2.0)
    parser.add_argument("--sweeps", type=int, default=5)
    parser.add_argument("--camera", action="store_true", help="also measure the camera test (slow: renders)")
    parser.add_argument("--margin", action="store_true", help="only the motions below the targets")
    args = parser.parse_args()
    thresholds = StillThresholds.from_tolerance(0.2)
    print(f"thresholds from a 0.2 deg tolerance: LiDAR {thresholds.rotation_deg:.3f} deg, "
          f"{thresholds.translation_m * 1000:.2f} mm from a window's first sweep")
    for name, disturbance in (MARGIN if args.margin else CONDITIONS).items():
        started = time.perf_counter()
        results = [run_stop(stop, Disturbance(**{**disturbance.to_yaml(), "seed": stop}), args.seconds,
                            args.still_seconds, args.sweeps) for stop in range(args.stops)]
        print(report(name, results, args.still_seconds), f"[{time.perf_counter() - started:.0f} s]", flush=True)
    if args.camera:
        camera_figures(min(args.stops, 6))


if __name__ == "__main__":
    main()
