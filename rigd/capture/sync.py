"""Whether a pair's LiDAR sweeps can be shown to lie in the still window on the host clock, and what its metadata
says about the LiDAR's clock."""

from __future__ import annotations

from typing import Any

from drivers.vlp16 import ClockStep, Sweep

# A sweep's packets received more than this off its device time on the host clock (or outside the still
# window): the LiDAR's clock mapping is not what the window was built on, so the pair is not taken. Receive
# delays stay in milliseconds; half a turn still puts the sweep at the right turn.
SYNC_BOUND_S = 0.05


def sync_problem(sweeps: list[Sweep], window: tuple[float, float], clock_steps: tuple[ClockStep, ...]) -> str | None:
    """Why the sweeps cannot be shown to lie in the still window on the host clock, or None. Each sweep's
    own packets measure its host-minus-device offset; the window was built with its clock segment's."""
    for sweep in sweeps:
        lag = sweep.receive_offset_s - sweep.clock_offset_s
        if not abs(lag) <= SYNC_BOUND_S:
            return (f"a LiDAR sweep's packets arrived {lag:+.3f} s off its device time on the host clock (host "
                    f"minus device: measured {sweep.receive_offset_s:+.3f} s, used {sweep.clock_offset_s:+.3f} s; "
                    f"bound {SYNC_BOUND_S} s): the LiDAR's clock is not settled")
        if sweep.start.host < window[0] - SYNC_BOUND_S or sweep.end.host > window[1] + SYNC_BOUND_S:
            return (f"a LiDAR sweep was received at {sweep.start.host:.3f}-{sweep.end.host:.3f} s, outside the "
                    f"still window {window[0]:.3f}-{window[1]:.3f} s (host clock)")
    steps = [s for s in clock_steps if s.host_s > window[0]]
    if steps:
        return f"the LiDAR's clock stepped {steps[-1].step_s:+.3f} s inside the still window"
    return None


def sync_meta(sweeps: list[Sweep], clock_steps: tuple[ClockStep, ...]) -> dict[str, Any]:
    """The LiDAR's host-minus-device offset as used (its clock segment's) and as measured on the fused
    sweeps' own packets, and every clock step seen so far in this capture."""
    return {
        "lidar_offset_used_s": float(sweeps[-1].clock_offset_s),
        "lidar_offset_measured_s": float(min(s.receive_offset_s for s in sweeps)),
        "lidar_receive_lag_s": float(max(s.receive_offset_s - s.clock_offset_s for s in sweeps)),
        "bound_s": SYNC_BOUND_S,
        "lidar_clock_steps": [{"host_time_s": float(s.host_s), "step_s": float(s.step_s), "seen": s.kind.value}
                              for s in clock_steps],
    }
