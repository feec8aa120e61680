"""The assessed pinhole default against plain NID from the same starts: two convergence reports compared run by run.

Run (one dataset, the same --trials/--rot-deg/--trans-m/--seed for both, so both draw the same starts):
    rigd evaluate convergence SET --method nid --trials 5 --rot-deg 2 --trans-m 0.05 --seed 1 --out A
    rigd evaluate convergence SET --method nid-assessed --trials 5 --rot-deg 2 --trans-m 0.05 --seed 1 --out B
    .venv/bin/python benchmarks/assessed_vs_plain.py A/convergence.yaml B/convergence.yaml [--noise C/convergence.yaml]
(C: --method nid with --rot-deg 2.000001 --trans-m 0.05000001, the same starts 1e-6 deg / m away: how far plain NID
moves on its own, docs/baselines.md)

Prints each start's rotation / translation error against the reports' reference (the dataset's ground truth or
reference.yaml) for both, the assessed run's verdict, and how much farther from the reference the assessed run
ends (positive: worse), and with --noise how far plain NID's own result moves; then each method's median and
worst error.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from calib.evaluate import pose_error
from calib.geometry import Transform
from rigd.dataset.records import transform_from_yaml


def _load(path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise SystemExit(f"assessed_vs_plain: {path} is not a readable report: {exc}") from exc
    if not isinstance(data, dict) or data.get("protocol") != "convergence":
        raise SystemExit(f"assessed_vs_plain: {path} is not a convergence report")
    return data


def _pose(run: dict[str, Any], key: str) -> Transform | None:
    value = run.get(key)
    if value is None:
        return None
    return Transform.from_rpy_xyz(np.asarray(value["rpy_deg"], float), np.asarray(value["xyz_m"], float))


def _errors(report: dict[str, Any], reference: Transform) -> list[tuple[float, float] | None]:
    """Per run (rotation deg, translation cm) from the reference; None where the run raised."""
    out: list[tuple[float, float] | None] = []
    for run in report["runs"]:
        pose = _pose(run, "result")
        error = None if pose is None else pose_error(pose, reference)
        out.append(None if error is None else (error.rotation_deg, error.translation_cm))
    return out


def _same_starts(plain: dict[str, Any], other: dict[str, Any], within: float = 1e-9) -> None:
    """Exit unless both reports ran from the same starts (each pair within ``within`` deg and cm)."""
    a = [_pose(r, "start") for r in plain["runs"]]
    b = [_pose(r, "start") for r in other["runs"]]
    if len(a) != len(b) or any(p is None or q is None or max(pose_error(p, q)[:2]) > within
                               for p, q in zip(a, b, strict=True)):
        raise SystemExit("assessed_vs_plain: the two reports did not start from the same poses")


def _summary(name: str, errors: list[tuple[float, float] | None]) -> str:
    done = np.array([e for e in errors if e is not None])
    if not len(done):
        return f"{name}: no finished run"
    med, worst = np.median(done, axis=0), done.max(axis=0)
    return (f"{name}: median {med[0]:.3f} deg / {med[1]:.2f} cm, worst {worst[0]:.3f} deg / {worst[1]:.2f} cm "
            f"({len(done)} runs)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("plain", type=Path, help="convergence.yaml of --method nid")
    parser.add_argument("assessed", type=Path, help="convergence.yaml of --method nid-assessed, the same starts")
    parser.add_argument("--noise", type=Path, help="convergence.yaml of --method nid from starts 1e-6 away "
                        "(--rot-deg 2.000001 --trans-m 0.05000001): NID's own run-to-run change")
    args = parser.parse_args()
    plain, assessed = _load(args.plain), _load(args.assessed)
    _same_starts(plain, assessed)
    noise = None
    if args.noise is not None:
        noise = _load(args.noise)
        _same_starts(plain, noise, within=1e-4)
    reference = transform_from_yaml(assessed["reference"]["T_camera_lidar"], str(args.assessed))
    e_plain, e_assessed = _errors(plain, reference), _errors(assessed, reference)
    e_noise: list[tuple[float, float] | None] = _errors(noise, reference) if noise is not None else \
        [None] * len(e_plain)
    print(f"reference: {assessed['reference']['source']}")
    print("start  plain deg / cm     assessed deg / cm  verdict   assessed - plain      plain 1e-6 away - plain")
    for i, (p, a, n) in enumerate(zip(e_plain, e_assessed, e_noise, strict=True)):
        verdict = assessed["runs"][i].get("verdict") or "-"
        if p is None or a is None:
            print(f"{i:5d}  {p}  {a}  {verdict}")
            continue
        jitter = "" if n is None else f"{n[0] - p[0]:+.3f} deg / {n[1] - p[1]:+.2f} cm"
        print(f"{i:5d}  {p[0]:6.3f} / {p[1]:6.2f}    {a[0]:6.3f} / {a[1]:6.2f}    {verdict:8s}  "
              f"{a[0] - p[0]:+.3f} deg / {a[1] - p[1]:+.2f} cm   {jitter}")
    print(_summary("nid", e_plain))
    print(_summary("nid-assessed", e_assessed))
    if noise is not None:
        print(_summary("nid from starts 1e-6 away", e_noise))


if __name__ == "__main__":
    main()
