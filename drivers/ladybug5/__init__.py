"""FLIR Ladybug5/5+ adapter (docs/ladybug5.md).

Without FLIR's SDK: USB presence and health (usb), .pgr and directory replay (pgr, replay), stitching
(rig, stitch), camera->host time mapping (clock). With the SDK: live frames through a thin ctypes binding
(sdk). The simulated rig's camera is ``drivers.ladybug5.sim.SimFrameSource`` (imported on its own so the
adapter does not load the simulator).
"""

from drivers.ladybug5.clock import ClockReport, ClockSync, unwrap_times
from drivers.ladybug5.errors import (
    CameraNotFoundError,
    CorruptFrameError,
    InterfaceSpeedError,
    Ladybug5Error,
    LibraryMissingError,
    MissingPowerError,
    RigFileError,
    SdkError,
    StreamFormatError,
    UsbBackendError,
)
from drivers.ladybug5.frames import Exposure, FrameSource, PanoramaFrame, SkipCounter, TimeBase
from drivers.ladybug5.pgr import PgrLayout, PgrStream, write_pgr
from drivers.ladybug5.replay import DirectoryFrameSource, PgrFrameSource
from drivers.ladybug5.rig import RigCamera, RigCameras, default_ladybug5_rig, load_rig, save_rig
from drivers.ladybug5.sdk import DataFormat, DeviceTimeField, LadybugLibrary, SdkCamera, SdkFrameSource, SdkLayout
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher
from drivers.ladybug5.usb import UsbCamera, UsbMatch, UsbSpeed, find_cameras, require_camera, reset_camera

__all__ = [
    "CameraNotFoundError",
    "ClockReport",
    "ClockSync",
    "CorruptFrameError",
    "DataFormat",
    "DeviceTimeField",
    "DirectoryFrameSource",
    "Exposure",
    "FrameSource",
    "InterfaceSpeedError",
    "LadybugLibrary",
    "Ladybug5Error",
    "LibraryMissingError",
    "MissingPowerError",
    "PanoramaFrame",
    "PanoramaSpec",
    "PgrFrameSource",
    "PgrLayout",
    "PgrStream",
    "RigCamera",
    "RigCameras",
    "RigFileError",
    "SdkCamera",
    "SdkError",
    "SdkFrameSource",
    "SdkLayout",
    "SkipCounter",
    "Stitcher",
    "StreamFormatError",
    "TimeBase",
    "UsbBackendError",
    "UsbCamera",
    "UsbMatch",
    "UsbSpeed",
    "default_ladybug5_rig",
    "find_cameras",
    "load_rig",
    "require_camera",
    "reset_camera",
    "save_rig",
    "unwrap_times",
    "write_pgr",
]
