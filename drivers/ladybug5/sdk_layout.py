"""What the ctypes binding needs from the installed SDK's headers, measured by layout_probe.c (never written here).

``rigd camera sdk-layout --include DIR`` compiles ``layout_probe.c`` against ``DIR/ladybug.h``,
``ladybuggeom.h`` and ``ladybugrenderer.h`` and saves its YAML: struct offsets and sizes of ``LadybugImage``,
``LadybugCameraInfo``, ``LadybugProcessedImage``, ``LadybugImage3d`` and ``LadybugPoint3d``, and the values of the
enum members the binding uses (errors, data formats, properties, Bayer formats, output image types, pixel formats,
colour processing methods). The SDK's enums are ordinal and grew between versions, so these numbers belong to the
installed SDK, not to rigd.
"""

from __future__ import annotations

import subprocess
import tempfile
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import yaml

from drivers.ladybug5.errors import Ladybug5Error

PROBE_SOURCE = Path(__file__).with_name("layout_probe.c")
IMAGE_FIELDS = ("cols", "rows", "full_cols", "full_rows", "border_top", "border_bottom", "border_left",
                "border_right", "data_format", "stippled_format", "cycle_seconds", "cycle_count", "embedded_seconds",
                "embedded_microseconds", "sequence_id", "data", "data_size")
CAMERA_INFO_FIELDS = ("serial_head", "model_name")
PROCESSED_IMAGE_FIELDS = ("cols", "rows", "data", "pixel_format")
IMAGE3D_FIELDS = ("rows", "cols", "points")  # ladybugGet3dMap's result (ladybuggeom.h)
POINT3D_FIELDS = ("x", "y", "z")
# enum members the binding needs by name, per section (the probe prints more)
REQUIRED_VALUES = {"output_images": ("ALL_RECTIFIED_IMAGES", "PANORAMIC"), "pixel_formats": ("BGR", "BGRU", "BGRU16"),
                   "color_methods": ("EDGE_SENSING", "NEAREST_NEIGHBOR_FAST", "RIGOROUS", "HQLINEAR")}


def _fields(data: Any, key: str) -> dict[str, tuple[int, int]]:
    return {str(k): (int(v[0]), int(v[1])) for k, v in data[key].items()}


def _values(data: Any, key: str) -> dict[str, int]:
    return {str(k): int(v) for k, v in data[key].items()}


@dataclass(frozen=True)
class SdkLayout:
    """What layout_probe.c measured: ``*_fields`` map a name to (offset, size) in bytes; the rest map the
    ``LADYBUG_`` member name (without the prefix, formats without ``DATAFORMAT_``) to its value."""

    image_size: int
    image_fields: dict[str, tuple[int, int]]
    camera_info_size: int
    camera_info_fields: dict[str, tuple[int, int]]
    errors: dict[str, int]
    formats: dict[str, int]
    properties: dict[str, int]
    stippled: dict[str, int]
    output_images: dict[str, int]
    processed_image_size: int
    processed_image_fields: dict[str, tuple[int, int]]
    pixel_formats: dict[str, int]
    color_methods: dict[str, int]
    image3d_fields: dict[str, tuple[int, int]]
    point3d_size: int
    point3d_fields: dict[str, tuple[int, int]]

    def format_name(self, code: int) -> str | None:
        """The data format's name of an SDK value (None when the probe did not list it)."""
        return next((name for name, value in self.formats.items() if value == code), None)

    @classmethod
    def from_yaml(cls, data: Any, where: str) -> SdkLayout:
        keys = [f.name for f in fields(cls)]
        missing = [k for k in keys if not isinstance(data, dict) or k not in data]
        if missing:
            raise Ladybug5Error(f"{where}: not a Ladybug SDK layout of this rigd's layout_probe.c (missing "
                                f"{', '.join(missing)}); measure it again: rigd camera sdk-layout --include DIR --out "
                                f"{where}")
        try:
            layout = cls(int(data["image_size"]), _fields(data, "image_fields"), int(data["camera_info_size"]),
                         _fields(data, "camera_info_fields"), _values(data, "errors"), _values(data, "formats"),
                         _values(data, "properties"), _values(data, "stippled"), _values(data, "output_images"),
                         int(data["processed_image_size"]), _fields(data, "processed_image_fields"),
                         _values(data, "pixel_formats"), _values(data, "color_methods"),
                         _fields(data, "image3d_fields"), int(data["point3d_size"]), _fields(data, "point3d_fields"))
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise Ladybug5Error(f"{where}: not a Ladybug SDK layout from layout_probe.c ({exc!r})") from exc
        absent = [f for f in IMAGE_FIELDS if f not in layout.image_fields]
        absent += [f for f in CAMERA_INFO_FIELDS if f not in layout.camera_info_fields]
        absent += [f for f in PROCESSED_IMAGE_FIELDS if f not in layout.processed_image_fields]
        absent += [f"image3d.{f}" for f in IMAGE3D_FIELDS if f not in layout.image3d_fields]
        absent += [f"point3d.{f}" for f in POINT3D_FIELDS if f not in layout.point3d_fields]
        absent += [f"{section}.{name}" for section, names in REQUIRED_VALUES.items() for name in names
                   if name not in getattr(layout, section)]
        if absent:
            raise Ladybug5Error(f"{where}: the layout lacks {', '.join(absent)}; measure it again with this rigd's "
                                "rigd camera sdk-layout")
        return layout

    @classmethod
    def load(cls, path: Path) -> SdkLayout:
        try:
            return cls.from_yaml(yaml.safe_load(Path(path).read_text()), str(path))
        except (OSError, yaml.YAMLError) as exc:
            raise Ladybug5Error(f"cannot read SDK layout file {path}: {exc}") from exc


def probe_layout(include_dir: Path, compiler: str = "c++", out: Path | None = None) -> SdkLayout:
    """Compile and run layout_probe.c against ``include_dir``'s SDK headers; optionally save the YAML."""
    with tempfile.TemporaryDirectory() as tmp:
        exe = Path(tmp) / "ladybug_layout_probe"
        cmd = [compiler, "-I", str(include_dir), "-o", str(exe), str(PROBE_SOURCE)]
        try:
            build = subprocess.run(cmd, capture_output=True, text=True, check=False)
        except OSError as exc:
            raise Ladybug5Error(f"cannot run compiler {compiler!r}: {exc}") from exc
        if build.returncode != 0:
            raise Ladybug5Error(
                f"layout_probe.c does not compile against {include_dir}/ladybug.h, ladybuggeom.h and "
                f"ladybugrenderer.h (is that the Ladybug SDK's include directory?):\n{build.stderr[-2000:]}"
            )
        text = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    if out is not None:
        Path(out).write_text(text)
    return SdkLayout.from_yaml(yaml.safe_load(text), f"output of {PROBE_SOURCE.name}")
