"""A captured pair's ``meta.yaml``: its camera frame, the LiDAR sweeps fused, their clocks and synchronisation,
and the stillness and motion the pair was taken on (docs/dataset.md)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.vlp16 import ClockStep, Sweep
from rigd.capture.gate import StillnessGate, SweepSample
from rigd.capture.records import CaptureRequest
from rigd.capture.sources import CameraFrame
from rigd.capture.sync import sync_meta
from rigd.dataset import Cloud
from rigd.version import software_version


@dataclass(frozen=True)
class TakenPair:
    """What a pair is made of: the frame (at host time ``frame_t`` s), the sweeps chosen for it with their
    samples, their fused cloud, the still window (host s) and how far the rig moved since the previous pair (m)."""

    frame_t: float
    frame: CameraFrame
    chosen: list[tuple[SweepSample, Sweep]]
    cloud: Cloud
    window: tuple[float, float]
    moved_m: float | None


def pair_meta(request: CaptureRequest, pair: TakenPair, gate: StillnessGate, *,
              clock_steps: tuple[ClockStep, ...], packets_lost: int) -> dict[str, Any]:
    """The pair's metadata; ``clock_steps`` and ``packets_lost``: the LiDAR stream's so far in this capture."""
    frame, frame_t, chosen, window = pair.frame.panorama, pair.frame_t, pair.chosen, pair.window
    sensors = pair.frame.sensors
    sweeps = [sw for _, sw in chosen]
    measured = min(s.receive_offset_s for s in sweeps)
    lidar_mid = 0.5 * (chosen[0][0].t_start + chosen[-1][0].t_end)
    return {
        "source": "captured",
        "software_version": software_version(),
        "camera": {
            "source": request.camera,
            "device_time_s": float(frame.device_time_s),
            "host_time_s": float(frame_t),
            "sequence_id": int(frame.sequence_id),
            "time_base": frame.time_base.value,
            "exposure": {"shutter_s": frame.exposure.shutter_s, "gain_db": frame.exposure.gain_db},
            **({} if sensors is None else {"head": sensors.head.summary(), "head_source": sensors.head.source.value}),
        },
        "lidar": _lidar_meta(request, sweeps, pair.cloud),
        "clock_offset_s": {"camera": float(frame_t - frame.device_time_s), "lidar": float(measured)},
        "sync": sync_meta(sweeps, clock_steps),
        "camera_minus_lidar_s": float(frame_t - lidar_mid),
        "still_window_host_s": [float(window[0]), float(window[1])],
        "motion": _motion_meta(request, gate, pair.moved_m),
        "stream": {"packets_lost_total": packets_lost},
    }


def _lidar_meta(request: CaptureRequest, sweeps: list[Sweep], cloud: Cloud) -> dict[str, Any]:
    first, last = sweeps[0], sweeps[-1]
    return {
        "source": request.lidar,
        "device_time_s": [float(first.start.device), float(last.end.device)],
        "host_time_s": [float(first.start.host), float(last.end.host)],
        "sweeps_fused": len(sweeps),
        "points": len(cloud),
        "rpm": float(np.median([s.rpm for s in sweeps])),
        "packets": int(sum(s.packet_count for s in sweeps)),
        "packets_lost": int(sum(s.missing_packets for s in sweeps)),
        "sweep_coverage": [round(float(s.coverage), 4) for s in sweeps],
        "min_sweep_fraction": request.min_sweep_fraction,
        "pps": last.pps.name.lower() if last.pps is not None else None,
        "time_source": last.time_source.value,
    }


def _motion_meta(request: CaptureRequest, gate: StillnessGate, moved_m: float | None) -> dict[str, Any]:
    camera_change, camera_limit = gate.camera_change(), gate.camera_threshold_deg()
    limits = gate.thresholds
    return {
        "still_seconds": request.still_seconds,
        "lidar_rotation_deg": float(gate.rotation_deg),
        "lidar_translation_m": float(gate.translation_m),
        "lidar_still_rotation_deg": limits.rotation_deg,
        "lidar_still_translation_m": limits.translation_m,
        "camera_change_deg": None if camera_change is None else float(camera_change),
        "camera_frames_in_window": len(gate.window_frames()),
        "camera_still_deg": None if camera_limit is None else float(camera_limit),
        "tolerance_deg": limits.tolerance_deg,
        "moved_since_previous_m": None if moved_m is None else float(moved_m),
        "min_move_m": request.min_move,
    }
