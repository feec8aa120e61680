"""A capture's request, its states, the status line the progress callback receives and the summary it returns."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from pathlib import Path

DEFAULT_MIN_MOVE_M = 0.5
DEFAULT_MIN_SWEEP_FRACTION = 0.99  # of a turn's packets, in every fused sweep


@dataclass(frozen=True)
class CaptureRequest:
    """A capture job: ``n`` pairs in the dataset ``out`` (counting pairs already there).

    Sources as in ``rigd capture`` (docs/capture.md); ``config``: the rig file for the dataset's rig.yaml
    (camera size, initial guess, the tolerance the stillness thresholds come from) and the SDK settings;
    None: built-in defaults. ``min_sweep_fraction``: every fused sweep holds at least this fraction of a
    turn's packets (0 < f <= 1). ``serial``: the SDK camera's head serial number (None: the rig file's
    camera.sdk.serial, else the only camera). ``nominal_head``: accept rigd's nominal head for the SDK camera
    (instead of reading its factory head when the rig file names no head file; refused otherwise).
    """

    out: Path
    n: int
    lidar: str = "sim"
    camera: str = "sim"
    still_seconds: float = 2.0
    sweeps: int = 5
    min_move: float = DEFAULT_MIN_MOVE_M
    silence_timeout_s: float = 5.0
    config: Path | None = None
    min_sweep_fraction: float = DEFAULT_MIN_SWEEP_FRACTION
    serial: int | None = None
    nominal_head: bool = False


class CaptureState(Enum):
    STARTING = "starting"
    WAITING_FOR_STOP = "waiting_for_stop"
    HOLDING_STILL = "holding_still"
    WAITING_FOR_FRAME = "waiting_for_frame"
    NOT_SYNCHRONISED = "not_synchronised"
    UNUSABLE_LIDAR = "unusable_lidar"
    NEED_MOVE = "need_move"
    CAPTURING = "capturing"
    CAPTURED = "captured"
    DONE = "done"
    STOPPED = "stopped"


@dataclass(frozen=True)
class CaptureStatus:
    """Passed to the progress callback on every state change and every 0.5 s; ``state`` is a CaptureState value."""

    state: str
    pairs_done: int
    pairs_wanted: int
    still_for_s: float
    packet_rate_hz: float
    packets_lost: int
    message: str


@dataclass(frozen=True)
class CaptureSummary:
    """The pairs this run wrote (folders) and the seconds each took (from the start or the previous pair)."""

    out: Path
    pairs: tuple[Path, ...]
    seconds_per_pair: tuple[float, ...]


Progress = Callable[[CaptureStatus], None]
