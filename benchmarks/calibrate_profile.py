"""Where ``rigd calibrate --no-visuals`` spends wall time, CPU time and memory, stage by stage.

Run: .venv/bin/python benchmarks/calibrate_profile.py [DATASET] [--simulate outdoor --seed 41 --width 1024]
     [--offset 2,-1.5,1,5,-4,3] [--serial] [--cprofile FILE] [--time-v]

Without DATASET a 12-pair simulated set is written to a temporary directory first. The calibration runs as
``rigd calibrate DATASET --no-visuals --init INIT`` does (rigd.calibration.run_calibration), from INIT = the
ground truth's roll, pitch, yaw, x, y, z plus ``--offset`` (deg, m; printed, so the CLI run can be repeated).
Stages are timed by wrapping the functions that implement them (inclusive times; a function called from
two stages counts in both): image edges (with L0 smoothing as a sub-row), point edges, field maps per rung,
k-d trees, each coarse-to-fine level, the alternative schedule, the trust assessment (restarts, uncertainty
and jackknife). Feature extraction runs in worker processes unless ``--serial``: only the serial run splits
it into stages. Peak RSS is the process's high-water mark (VmHWM), reset between the feature and the solve
phases where the kernel allows it. ``--time-v`` also runs the CLI under ``/usr/bin/time -v``.
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

import calib.assess
import calib.edges_image
import calib.fields
import calib.gmm
import calib.optimize
import calib.pipeline
import rigd.calibration.features
from calib.geometry import Transform
from rigd.calibration import CalibrationRequest, Start, TransformIn, run_calibration
from rigd.dataset import open_dataset
from rigd.simulate import write_simulated_dataset

WALL: dict[str, float] = defaultdict(float)
CPU: dict[str, float] = defaultdict(float)
CALLS: dict[str, int] = defaultdict(int)
ORDER: list[str] = []


@contextmanager
def stage(label: str) -> Iterator[None]:
    if label not in ORDER:
        ORDER.append(label)
    w, c = time.perf_counter(), time.process_time()
    try:
        yield
    finally:
        WALL[label] += time.perf_counter() - w
        CPU[label] += time.process_time() - c
        CALLS[label] += 1


def instrument(module: Any, name: str, label: Callable[..., str] | str) -> None:
    """Replace ``module.name`` by a wrapper that times each call under ``label`` (or ``label(*args)``)."""
    original = getattr(module, name)

    @functools.wraps(original)
    def timed(*args: Any, **kwargs: Any) -> Any:
        with stage(label if isinstance(label, str) else label(*args, **kwargs)):
            return original(*args, **kwargs)

    setattr(module, name, timed)


_depth = {"schedule": 0, "assess": 0}


def _schedule_label(feats: Any, tau0: Any, opts: Any, *rest: Any) -> str:
    if _depth["assess"]:
        return "assess: restart solves"
    _depth["schedule"] += 1
    return "optimise: main schedule" if _depth["schedule"] == 1 else "optimise: alternative schedule"


def _level_label(prob: Any, tau: Any, opts: Any, scale: Any, sigma_rad: float, *rest: Any) -> str:
    evaluator = prob.gmm.evaluator.value
    where = "assess restarts" if _depth["assess"] else "optimise"
    return f"  {where}: level {np.degrees(sigma_rad):.2f} deg ({evaluator})"


def _rung_label(score_map: Any, mask_map: Any, sigma: float, wrap_u: bool) -> str:
    return f"  field rung sigma {sigma:5.1f} px"


def _band_label(fields: Any, *args: Any) -> str:
    kernels = args[-1]  # the rung's kernels (and spectra) are _maps' last argument; before, rung k its first
    radius = kernels.radius if hasattr(kernels, "radius") else None
    if radius is None:
        return f"  field rung sigma {fields.sigmas_px[args[0]]:5.1f} px (band, on demand)"
    return f"  field band chunks, kernel radius {radius:3d} pooled px"


def install() -> None:
    instrument(calib.pipeline, "image_edge_pixels", "image edges (incl. L0)")
    instrument(calib.edges_image, "l0_smooth", "  L0 smoothing")
    instrument(calib.pipeline, "edge_points", "point edges")
    # Before issue 12 every rung was built with the features; after, rungs and row bands on demand.
    if hasattr(calib.fields, "_rung"):
        instrument(calib.fields.EdgeFields, "build", "field maps (all rungs)")
        instrument(calib.fields, "_rung", _rung_label)
    else:
        instrument(calib.fields.EdgeFields, "grow", "field maps (rung bands built on demand)")
        instrument(calib.fields.EdgeFields, "_maps", _band_label)
    instrument(calib.gmm, "_sums_exact", "exact sums (pixel enumeration)")
    if hasattr(calib.gmm, "sample_fields"):
        instrument(calib.gmm, "sample_fields", "field sampling (incl. bands built)")
    else:
        instrument(calib.gmm.EdgeFields, "sample", "field sampling (incl. bands built)")
    if hasattr(calib.pipeline, "cKDTree"):  # before the compiled exact sums (calib.pixel_grid)
        instrument(calib.pipeline, "cKDTree", "k-d tree of edge pixels")
    else:
        instrument(calib.pipeline.PixelGrid, "build", "pixel grid of edge pixels")
    instrument(calib.optimize, "_run_level", _level_label)
    instrument(calib.optimize, "_coarse_to_fine", _schedule_label)
    instrument(calib.assess, "_uncertainty", "assess: uncertainty (sandwich + jackknife)")
    original_assess = calib.pipeline.assess

    def assess(*args: Any, **kwargs: Any) -> Any:
        _depth["assess"] += 1
        with stage("assess: total (restarts + uncertainty)"):
            return original_assess(*args, **kwargs)

    calib.pipeline.assess = assess
    original_optimise = calib.pipeline.optimise if hasattr(calib.pipeline, "optimise") else None
    if original_optimise is not None:
        def optimise(*args: Any, **kwargs: Any) -> Any:
            _depth["schedule"] = 0
            with stage("optimise: total (both schedules)"):
                return original_optimise(*args, **kwargs)

        calib.pipeline.optimise = optimise


def _hwm_kb() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _reset_hwm() -> bool:
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def _init_text(dataset: Path, offset: list[float]) -> str:
    gt = open_dataset(dataset).ground_truth
    if gt is None:
        raise SystemExit(f"{dataset}: no ground_truth.yaml; this benchmark starts from the ground truth + --offset")
    values = np.concatenate([gt.rpy_deg, gt.translation_m]) + np.array(offset)
    return ",".join(f"{v:.6f}" for v in values)


def _features_bytes(feats: list[Any]) -> int:
    total = 0
    for f in feats:
        if f.fields is not None:
            total += sum(r.maps.nbytes for r in getattr(f.fields, "rungs", ()) if r is not None)
    return total


def run(dataset: Path, init: str, serial: bool, profile: str | None) -> dict[str, Any]:
    """One calibration as the CLI runs it, with the stage timers installed."""
    install()
    hwm: dict[str, int] = {}
    original_features = rigd.calibration.features.dataset_features

    def features(*args: Any, **kwargs: Any) -> Any:
        with stage("features: total (load + edges + fields + trees)"):
            feats = original_features(*args, **kwargs)
        hwm["features"] = _hwm_kb()
        hwm["features_bytes"] = _features_bytes(feats)
        hwm["reset_ok"] = int(_reset_hwm())
        return feats

    rigd.calibration.features.dataset_features = features
    parts = [float(v) for v in init.split(",")]
    start = Transform.from_rpy_xyz(np.array(parts[:3]), np.array(parts[3:]))
    request = CalibrationRequest(dataset=dataset, out_dir=Path(tempfile.mkdtemp(prefix="rigd-prof-")),
                                 start=Start.GIVEN, initial=TransformIn.of(start), write_visuals=False,
                                 workers=1 if serial else 2)
    profiler = cProfile.Profile() if profile else None
    start_w, start_c = time.perf_counter(), time.process_time()
    if profiler:
        profiler.enable()
    outcome = run_calibration(request)
    if profiler:
        profiler.disable()
        profiler.dump_stats(profile)
    WALL["TOTAL run_calibration"] = time.perf_counter() - start_w
    CPU["TOTAL run_calibration"] = time.process_time() - start_c
    ORDER.append("TOTAL run_calibration")
    hwm["solve"] = _hwm_kb()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    hwm["children_max"] = children.ru_maxrss
    hwm["children_cpu"] = int((children.ru_utime + children.ru_stime) * 1000)
    return {"outcome": outcome, "hwm": hwm}


def print_table(result: dict[str, Any]) -> None:
    print(f"{'stage':58s} {'wall s':>8s} {'cpu s':>8s} {'calls':>6s}")
    rungs = sorted((label for label in ORDER if label.startswith("  field rung")),
                   key=lambda label: float(label.split()[3]))
    for label in ORDER:
        if label in rungs:
            continue
        for row in [label, *(rungs if label.startswith("field maps") else [])]:
            print(f"{row:58s} {WALL[row]:8.2f} {CPU[row]:8.2f} {CALLS[row] or 1:6d}")
    hwm = result["hwm"]
    print(f"peak RSS after features: {hwm['features'] / 1024:.0f} MB "
          f"(field maps held: {hwm['features_bytes'] / 2**20:.0f} MB)")
    solve = "after reset" if hwm["reset_ok"] else "whole run (reset not allowed)"
    print(f"peak RSS of the solve ({solve}): {hwm['solve'] / 1024:.0f} MB")
    if hwm["children_max"]:
        print(f"worker processes: peak RSS {hwm['children_max'] / 1024:.0f} MB, CPU {hwm['children_cpu'] / 1000:.2f} s")
    report = result["outcome"].report
    t = report["T_camera_lidar"]
    print(f"T_camera_lidar rpy_deg {np.round(t['rpy_deg'], 4).tolist()} xyz_m {np.round(t['xyz_m'], 5).tolist()}")
    if "error_vs_ground_truth" in report:
        e = report["error_vs_ground_truth"]
        print(f"error vs ground truth: {e['rotation_deg']:.4f} deg, {e['translation_cm']:.3f} cm")
    u = report.get("uncertainty")
    if u:
        print(f"sigma rpy_deg {np.round(np.array(u['rpy_deg'], dtype=float), 4).tolist()} "
              f"xyz_cm {np.round(np.array(u['xyz_cm'], dtype=float), 3).tolist()}; "
              f"verdict {report['verdict']['status']}")
    print(f"final cost {report['quality']['final_cost']:.6f}")


def time_v(dataset: Path, init: str) -> None:
    """The CLI end to end under /usr/bin/time -v: wall, user CPU, peak RSS."""
    with tempfile.TemporaryDirectory() as out:
        cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "rigd", "calibrate", str(dataset), "--no-visuals",
               "--init", init, "--out", out]
        proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ}, check=False)
    keys = ("Elapsed (wall clock)", "User time", "System time", "Maximum resident set size", "Exit status")
    print("$ " + " ".join(cmd[2:]))
    for line in proc.stderr.splitlines():
        if line.strip().startswith(keys):
            print("  " + line.strip())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", nargs="?", type=Path)
    parser.add_argument("--simulate", choices=["indoor", "outdoor"], default="outdoor")
    parser.add_argument("--seed", type=int, default=41)
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--pairs", type=int, default=12)
    parser.add_argument("--offset", type=str, default="2,-1.5,1,0.05,-0.04,0.03",
                        help="added to the ground truth's roll,pitch,yaw (deg),x,y,z (m) for the initial guess")
    parser.add_argument("--serial", action="store_true", help="extract features in this process (stage split)")
    parser.add_argument("--cprofile", type=str, default=None, help="also write cProfile stats to this file")
    parser.add_argument("--time-v", action="store_true", help="also run the CLI under /usr/bin/time -v")
    args = parser.parse_args()
    dataset = args.dataset
    tmp = None
    if dataset is None:
        tmp = tempfile.TemporaryDirectory()
        dataset = Path(tmp.name) / "ds"
        write_simulated_dataset(dataset, args.simulate, args.pairs, args.seed, args.width, args.width // 2,
                                progress=False)
    init = _init_text(dataset, [float(v) for v in args.offset.split(",")])
    print(f"dataset {dataset}  init {init}  load {os.getloadavg()[0]:.2f}")
    print_table(run(dataset, init, args.serial, args.cprofile))
    if args.time_v:
        time_v(dataset, init)
    print(f"load average at the end {os.getloadavg()[0]:.2f}")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
