"""The head calibration file written by ``rigd camera export-head`` and its rectification maps.

``head.yaml``::

    head:                                  # what the SDK reported, and where it came from
      source: factory                      # factory | nominal | file
      description: camera 17092345 (ladybugLoadConfig from the head)
      serial: 17092345
      maps: head.maps.npz                  # the sampled rectification, beside this file (null: none)
      sensors:
        - name: cam0
          focal_px: 452.3                  # rectified, at the raw size (a Ladybug5: 443-464 px)
          centre_px: [1251.2, 1038.4]
          extrinsics: [rx, ry, rz, tx, ty, tz]   # ladybugGetCameraUnitExtrinsics: Euler ZYX rad, m
          fit: {rms_px: 0.08, max_px: 0.31, points: 20000, folds: false}
    camera:                                # the head dataset format's sensor form (docs/dataset.md)
      model: head
      sensors:
        - {name: cam0, model: pinhole, width: 2448, height: 2048, K: ..., D: [k1, k2, p1, p2, k3],
           T_head_camera: {matrix, quaternion_xyzw, rpy_deg, xyz_m}}

The ``camera`` section is also what a rig camera file reader (:func:`drivers.ladybug5.rig.load_rig`) and a
dataset's rig.yaml take, so the file can be given as ``camera.sdk.rig_file`` and copied into a head dataset.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from drivers.ladybug5.errors import HeadCalibrationError, RigFileError
from drivers.ladybug5.head import HeadCalibration, HeadSource, LensFit, RectificationMaps, SensorCalibration
from drivers.ladybug5.rig import rig_from_yaml, transform_yaml


def head_to_yaml(head: HeadCalibration, maps_name: str | None) -> dict[str, Any]:
    """The YAML mapping of ``head``; ``maps_name``: the maps file's name relative to the YAML (None: none)."""
    meta = [{"name": s.name, "focal_px": float(s.focal_px), "centre_px": [float(v) for v in s.centre_px],
             "extrinsics": [float(v) for v in s.extrinsics],
             "fit": {"rms_px": float(s.lens.rms_px), "max_px": float(s.lens.max_px), "points": int(s.lens.points),
                     "folds": bool(s.lens.folds)}} for s in head.sensors]
    sensors = [{"name": s.name, "model": "pinhole", "width": s.width, "height": s.height, "K": s.lens.K.tolist(),
                "D": s.lens.D.tolist(), "T_head_camera": transform_yaml(s.R_head_camera, s.t_head_camera_m)}
               for s in head.sensors]
    return {"head": {"source": head.source.value, "description": head.description, "serial": head.serial,
                     "maps": maps_name, "sensors": meta},
            "camera": {"model": "head", "sensors": sensors}}


def save_head(head: HeadCalibration, path: Path, maps_path: Path | None = None) -> None:
    """Write ``head`` to ``path`` (YAML) and, when it has rectification maps, to ``maps_path`` (default:
    ``path`` with ``.maps.npz``), named relative to the YAML."""
    path = Path(path)
    has_maps = all(s.maps is not None for s in head.sensors)
    maps_path = (maps_path or path.with_suffix(".maps.npz")) if has_maps else None
    if maps_path is not None:
        arrays = {f"{key}_{s.name}": getattr(s.maps, key) for s in head.sensors
                  for key in ("grid_x", "grid_y", "raw_to_rect", "rect_to_raw")}
        np.savez_compressed(maps_path, **arrays)
    name = None if maps_path is None else _relative(Path(maps_path), path.parent)
    path.write_text(yaml.safe_dump(head_to_yaml(head, name), sort_keys=False, width=120, default_flow_style=None))


def _relative(path: Path, directory: Path) -> str:
    """``path`` relative to ``directory`` when it lies below it, else absolute."""
    try:
        return str(path.resolve().relative_to(directory.resolve()))
    except ValueError:  # elsewhere: the head file names it absolutely
        return str(path.resolve())


def _maps(path: Path, name: str) -> RectificationMaps:
    try:
        with np.load(path) as npz:
            return RectificationMaps(*(np.asarray(npz[f"{key}_{name}"], dtype=np.float64)
                                       for key in ("grid_x", "grid_y", "raw_to_rect", "rect_to_raw")))
    except (OSError, KeyError, ValueError) as exc:
        raise HeadCalibrationError(f"{path}: no rectification maps of sensor {name} ({exc})") from exc


def _sensor(meta: dict[str, Any], rig_sensor: SensorCalibration, maps: RectificationMaps | None,
            where: str) -> SensorCalibration:
    try:
        fit = meta["fit"]
        lens = LensFit(rig_sensor.lens.K, rig_sensor.lens.D, float(fit["rms_px"]), float(fit["max_px"]),
                       int(fit["points"]), bool(fit["folds"]))
        e = [float(v) for v in meta["extrinsics"]]
        cx, cy = (float(v) for v in meta["centre_px"])
        return SensorCalibration(rig_sensor.name, rig_sensor.width, rig_sensor.height, float(meta["focal_px"]),
                                 (cx, cy), (e[0], e[1], e[2], e[3], e[4], e[5]), lens, maps)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise HeadCalibrationError(f"{where}: bad head.sensors entry of {rig_sensor.name} ({exc!r})") from exc


def load_head(path: Path) -> HeadCalibration:
    """A head calibration file, or a plain rig camera file (then ``source`` FILE, no maps)."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise HeadCalibrationError(f"cannot read head calibration file {path}: {exc}") from exc
    try:
        rig = rig_from_yaml(data, str(path))
    except RigFileError as exc:
        raise HeadCalibrationError(str(exc)) from exc
    plain = HeadCalibration.from_rig(rig, HeadSource.FILE, f"rig camera file {path}")
    meta = data.get("head") if isinstance(data, dict) else None
    if not isinstance(meta, dict):
        return plain
    try:
        source = HeadSource(str(meta.get("source")))
    except ValueError as exc:
        raise HeadCalibrationError(f"{path}: head.source must be one of {[s.value for s in HeadSource]}") from exc
    entries = {str(m.get("name")): m for m in meta.get("sensors") or [] if isinstance(m, dict)}
    maps_file = path.parent / str(meta["maps"]) if meta.get("maps") else None
    sensors = tuple(_sensor(entries[s.name], s, _maps(maps_file, s.name) if maps_file else None, str(path))
                    if s.name in entries else s for s in plain.sensors)
    serial = meta.get("serial")
    return HeadCalibration(sensors, source, str(meta.get("description", path)),
                           int(serial) if serial is not None else None)
