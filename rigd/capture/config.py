"""The rig configuration file (``rig.yaml`` / ``/etc/rigd/rig.yaml``): sensors, initial guess, capture defaults.

It is also a valid dataset ``rig.yaml`` (camera, lidar.model, initial_guess are read by
:class:`rigd.dataset.RigConfig`); the keys only capture uses are documented in docs/configuration.md.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from calib.assess import TrustOptions
from calib.geometry import Transform
from calib.prior import Prior
from calib.search import SearchOptions
from drivers.ladybug5.sdk import DEFAULT_GRAB_TIMEOUT_MS, DEFAULT_LIBRARY
from drivers.ladybug5.sdk_render import PanoramaBackend
from drivers.ladybug5.stitch import DEFAULT_RADIUS_M
from rigd.capture.errors import ConfigError
from rigd.dataset import CameraKind, RigConfig
from rigd.dataset.store import read_yaml_mapping
from rigd.errors import DatasetError

CONFIG_ENV = "RIGD_CONFIG"
SEARCH_PATHS = (Path("rig.yaml"), Path("/etc/rigd/rig.yaml"))
DEFAULT_LAYOUT_FILE = Path("/etc/rigd/ladybug_layout.yaml")


@dataclass(frozen=True)
class CaptureDefaults:
    """The ``capture:`` section: defaults of ``rigd capture``'s options (same names)."""

    n: int = 12
    still_seconds: float = 2.0
    sweeps: int = 5
    min_move: float = 0.5
    silence_timeout_s: float = 5.0
    out: Path | None = None
    min_sweep_fraction: float = 0.99  # of a turn's packets, in every fused sweep


@dataclass(frozen=True)
class SdkSettings:
    """The ``camera.sdk:`` section: what the live Ladybug5 source needs (docs/ladybug5.md)."""

    layout: Path = DEFAULT_LAYOUT_FILE  # written by `rigd camera sdk-layout`
    library: str = DEFAULT_LIBRARY
    # The head calibration (`rigd camera export-head`, or a rig camera file). None: the rig file itself when its
    # camera.model is head, else no head, which capture refuses unless the nominal head is accepted
    # (--nominal-head: drivers.ladybug5's nominal values, not a calibration of any camera).
    rig_file: Path | None = None
    radius_m: float = DEFAULT_RADIUS_M  # stitching sphere
    serial: int | None = None  # the camera's head serial number; None: the only camera on the bus
    grab_timeout_ms: int = DEFAULT_GRAB_TIMEOUT_MS  # ladybugSetGrabTimeout: a stalled camera times out
    panorama: PanoramaBackend = PanoramaBackend.RIGD_STITCHER  # rigd's stitcher, or the SDK's renderer (OpenGL)


@dataclass(frozen=True)
class RigSettings:
    """What capture takes from the rig file; ``path`` is None when no file was found (built-in defaults)."""

    path: Path | None = None
    width: int = 2048  # the panorama's (px): the stillness check, the overlays, a panorama dataset
    height: int = 1024
    head: bool = False  # camera.model is head: the rig file's camera section is the Ladybug5 head calibration
    camera_source: str = "sdk"
    lidar_model: str = "VLP-16"
    lidar_source: str = "udp"
    initial_guess: Transform | None = None
    prior: Prior | None = None  # the rig's drawing, carried into each dataset's rig.yaml (docs/trust.md)
    tolerance: TrustOptions | None = None
    search: SearchOptions | None = None
    lidar_elevation_offset_deg: float = 0.0  # the LiDAR's declared elevation offset and its sigma, carried too
    lidar_elevation_sigma_deg: float | None = None  # None: not declared (the LiDAR model's own applies)
    sdk: SdkSettings = field(default_factory=SdkSettings)
    capture: CaptureDefaults = field(default_factory=CaptureDefaults)


def find_config(explicit: Path | None = None) -> Path | None:
    """``explicit`` (must exist), else ``$RIGD_CONFIG`` (must exist), else ./rig.yaml, else /etc/rigd/rig.yaml."""
    if explicit is not None:
        if not Path(explicit).is_file():
            raise ConfigError(f"{explicit}: rig configuration file does not exist")
        return Path(explicit)
    env = os.environ.get(CONFIG_ENV)
    if env:
        if not Path(env).is_file():
            raise ConfigError(f"{env}: rig configuration file (from ${CONFIG_ENV}) does not exist")
        return Path(env)
    return next((p for p in SEARCH_PATHS if p.is_file()), None)


def load_settings(path: Path | None) -> RigSettings:
    """Read the rig file at ``path`` (None: built-in defaults); errors name the file and the key."""
    if path is None:
        return RigSettings()
    where = str(path)
    try:
        data = read_yaml_mapping(Path(path))
        rig = RigConfig.from_yaml(data, where) if "camera" in data else None
    except DatasetError as exc:
        raise ConfigError(str(exc)) from exc
    camera = _section(data, "camera", where)
    lidar = _section(data, "lidar", where)
    if rig is not None and rig.camera.kind not in (CameraKind.EQUIRECTANGULAR, CameraKind.HEAD):
        raise ConfigError(f"{where}: camera.model must be equirectangular or head (capture writes Ladybug5 "
                          f"panoramas, or its sensors' images), got {rig.camera.kind.value}")
    head = rig is not None and rig.camera.kind is CameraKind.HEAD
    defaults = RigSettings()
    return RigSettings(
        path=Path(path),
        width=rig.camera.width if rig and not head else defaults.width,
        height=rig.camera.height if rig and not head else defaults.height,
        head=head,
        camera_source=str(camera.get("source", defaults.camera_source)),
        lidar_model=rig.lidar_model if rig else str(lidar.get("model", defaults.lidar_model)),
        lidar_source=str(lidar.get("source", defaults.lidar_source)),
        initial_guess=rig.initial_guess if rig else None,
        prior=rig.prior if rig else None,
        tolerance=rig.tolerance if rig else None,
        search=rig.search if rig else None,
        lidar_elevation_offset_deg=rig.lidar_elevation_offset_deg if rig else 0.0,
        lidar_elevation_sigma_deg=rig.lidar_elevation_sigma_declared_deg if rig else None,
        sdk=_sdk(_section(camera, "sdk", f"{where}: camera"), where),
        capture=_capture(_section(data, "capture", where), where),
    )


def _section(data: dict[str, Any], key: str, where: str) -> dict[str, Any]:
    value = data.get(key) or {}
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: '{key}' must be a mapping, got {value!r}")
    return value


def _unknown(section: dict[str, Any], known: set[str], where: str) -> None:
    unknown = set(section) - known
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)} (known: {sorted(known)})")


def _number(section: dict[str, Any], key: str, default: float, where: str, minimum: float, strict: bool,
            infinite: bool = False) -> float:
    value = section.get(key, default)
    try:
        number = float(value)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where}.{key}: not a number: {value!r}") from exc
    bad_inf = math.isinf(number) and not infinite
    if math.isnan(number) or bad_inf or number < minimum or (strict and number == minimum):
        raise ConfigError(f"{where}.{key}: must be {'>' if strict else '>='} {minimum}, got {value!r}")
    return number


def _integer(section: dict[str, Any], key: str, default: int, where: str) -> int:
    value = section.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(f"{where}.{key}: must be a positive integer, got {value!r}")
    return value


def _capture(section: dict[str, Any], where: str) -> CaptureDefaults:
    base, here = CaptureDefaults(), f"{where}: capture"
    _unknown(section, set(CaptureDefaults.__dataclass_fields__), here)
    out = section.get("out")
    return CaptureDefaults(
        n=_integer(section, "n", base.n, here),
        still_seconds=_number(section, "still_seconds", base.still_seconds, here, 0.0, strict=True),
        sweeps=_integer(section, "sweeps", base.sweeps, here),
        min_move=_number(section, "min_move", base.min_move, here, 0.0, strict=False),
        silence_timeout_s=_number(section, "silence_timeout_s", base.silence_timeout_s, here, 0.0, strict=True),
        out=Path(str(out)) if out is not None else None,
        min_sweep_fraction=_fraction(section, "min_sweep_fraction", base.min_sweep_fraction, here),
    )


def _fraction(section: dict[str, Any], key: str, default: float, where: str) -> float:
    value = _number(section, key, default, where, 0.0, strict=True)
    if value > 1.0:
        raise ConfigError(f"{where}.{key}: must be at most 1 (a fraction of a turn's packets), got {value!r}")
    return value


def _sdk(section: dict[str, Any], where: str) -> SdkSettings:
    base, here = SdkSettings(), f"{where}: camera.sdk"
    _unknown(section, set(SdkSettings.__dataclass_fields__), here)
    rig_file = section.get("rig_file")
    return SdkSettings(
        layout=Path(str(section.get("layout", base.layout))),
        library=str(section.get("library", base.library)),
        rig_file=Path(str(rig_file)) if rig_file is not None else None,
        radius_m=_number(section, "radius_m", base.radius_m, here, 0.0, strict=True, infinite=True),
        serial=_serial(section.get("serial"), here),
        grab_timeout_ms=_integer(section, "grab_timeout_ms", base.grab_timeout_ms, here),
        panorama=_panorama_backend(section.get("panorama", base.panorama.value), here),
    )


def _panorama_backend(value: Any, where: str) -> PanoramaBackend:
    choices = [b.value for b in PanoramaBackend]
    if value not in choices:
        raise ConfigError(f"{where}.panorama: must be one of {', '.join(choices)}, got {value!r}")
    return PanoramaBackend(value)


def _serial(value: Any, where: str) -> int | None:
    """A head serial number (a positive integer), or None."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(f"{where}.serial: must be the camera's head serial number (a positive integer), got "
                          f"{value!r}")
    return value
