"""The capture daemon: still, synchronised camera/LiDAR pairs at a dozen places (docs/capture.md).

Used by ``rigd capture`` and the HTTP service::

    from rigd.capture import CaptureRequest, run_capture
    summary = run_capture(CaptureRequest(out=Path("ds"), n=12, lidar="udp", camera="sdk"), print, stop_event)
"""

from rigd.capture.engine import run_capture
from rigd.capture.errors import (
    CaptureError,
    ConfigError,
    DiskFullError,
    SensorSilenceError,
    SimRigEndedError,
    SourceEndedError,
    SourceSpecError,
    SyncError,
)
from rigd.capture.records import CaptureRequest, CaptureState, CaptureStatus, CaptureSummary

__all__ = [
    "CaptureError",
    "CaptureRequest",
    "CaptureState",
    "CaptureStatus",
    "CaptureSummary",
    "ConfigError",
    "DiskFullError",
    "SensorSilenceError",
    "SimRigEndedError",
    "SourceEndedError",
    "SourceSpecError",
    "SyncError",
    "run_capture",
]
