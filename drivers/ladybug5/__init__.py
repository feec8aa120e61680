"""FLIR Ladybug5/5+ adapter (docs/ladybug5.md).

Without FLIR's SDK: USB presence and health (usb), .pgr and directory replay (pgr, replay) with FLIR's exports
(exports), channel JPEGs judged one by one (channels), RAW and 12/16-bit decoding (raw), stitching (rig, stitch),
another panorama's orientation (pano_check), head calibration files (head, head_file), camera->host time mapping
(clock). With the SDK: live frames -- six raw sensor images with the factory head calibration, or panoramas --
through a thin ctypes binding (sdk_layout, sdk_library, sdk, sdk_head, sdk_source). The simulated rig's camera is
``drivers.ladybug5.sim.SimFrameSource`` (imported on its own so the adapter does not load the simulator).
"""

from drivers.ladybug5.clock import ClockReport, ClockSync, unwrap_times
from drivers.ladybug5.errors import (
    CameraNotFoundError,
    CorruptFrameError,
    HeadCalibrationError,
    InterfaceSpeedError,
    Ladybug5Error,
    LibraryMissingError,
    MissingPowerError,
    RigFileError,
    SdkError,
    StreamFormatError,
    UnsupportedFormatError,
    UsbBackendError,
)
from drivers.ladybug5.formats import BayerPattern, DataFormat
from drivers.ladybug5.frames import (
    Exposure,
    FrameSource,
    PanoramaFrame,
    SensorFrame,
    SensorFrameSource,
    SkipCounter,
    TimeBase,
)
from drivers.ladybug5.head import HeadCalibration, HeadSource, SensorCalibration
from drivers.ladybug5.head_file import load_head, save_head
from drivers.ladybug5.pgr import PgrLayout, PgrStream, write_pgr
from drivers.ladybug5.replay import DirectoryFrameSource, PgrFrameSource
from drivers.ladybug5.rig import (
    LADYBUG5_SIZE_PX,
    LADYBUG5P_SIZE_PX,
    RigCamera,
    RigCameras,
    default_ladybug5_rig,
    load_rig,
    save_rig,
)
from drivers.ladybug5.sdk import DeviceTimeField, LadybugLibrary, SdkCamera, SdkLayout, enumerate_cameras
from drivers.ladybug5.sdk_head import head_from_config_file, head_from_pgr
from drivers.ladybug5.sdk_source import HeadPolicy, SdkFrameSource, SdkSensorSource
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher
from drivers.ladybug5.usb import UsbCamera, UsbMatch, UsbSpeed, find_cameras, require_camera, reset_camera

__all__ = [
    "LADYBUG5P_SIZE_PX",
    "LADYBUG5_SIZE_PX",
    "BayerPattern",
    "CameraNotFoundError",
    "ClockReport",
    "ClockSync",
    "CorruptFrameError",
    "DataFormat",
    "DeviceTimeField",
    "DirectoryFrameSource",
    "Exposure",
    "FrameSource",
    "HeadCalibration",
    "HeadCalibrationError",
    "HeadPolicy",
    "HeadSource",
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
    "SdkSensorSource",
    "SensorCalibration",
    "SensorFrame",
    "SensorFrameSource",
    "SkipCounter",
    "Stitcher",
    "StreamFormatError",
    "TimeBase",
    "UnsupportedFormatError",
    "UsbBackendError",
    "UsbCamera",
    "UsbMatch",
    "UsbSpeed",
    "default_ladybug5_rig",
    "enumerate_cameras",
    "find_cameras",
    "head_from_config_file",
    "head_from_pgr",
    "load_head",
    "load_rig",
    "require_camera",
    "reset_camera",
    "save_head",
    "save_rig",
    "unwrap_times",
    "write_pgr",
]
