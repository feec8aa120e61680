"""The panorama of a live Ladybug frame, by one of two backends: rigd's stitcher or the SDK's own renderer.

``PanoramaBackend.RIGD_STITCHER`` stitches the six decoded sensor images with :class:`Stitcher` from the frame's head
calibration (rigd's projection and blending, docs/ladybug5.md). ``PanoramaBackend.SDK_RENDERER`` hands the grabbed
``LadybugImage`` to FLIR's library: ``ladybugSetColorProcessingMethod``, ``ladybugConfigureOutputImages(PANORAMIC)``
and ``ladybugSetOffScreenImageSize(PANORAMIC, cols, rows)`` once per context, then per frame
``ladybugConvertImage`` into six BGRU textures (BGRU16 for RAW12, RAW16 and 12-bit JPEG), ``ladybugUpdateTextures`` and
``ladybugRenderOffScreenImage(PANORAMIC, BGR)``. The SDK renders with OpenGL: a rig computer without a GPU and an
OpenGL context fails at the configuration, which is a :class:`RendererError` (the stream ends; every frame would fail
alike); a render that fails later ends that frame only.
"""

from __future__ import annotations

import ctypes
from enum import Enum
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.errors import CorruptFrameError, Ladybug5Error, RendererError
from drivers.ladybug5.frames import SensorFrame
from drivers.ladybug5.raw import to_uint8
from drivers.ladybug5.sdk import SdkCamera
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher

CAMERAS = 6  # LADYBUG_NUM_CAMERAS
_BGR_BYTES = 3
_OPENGL_HINT = ("the SDK renders panoramas with OpenGL: it needs FLIR's library, a GPU and an OpenGL context on this "
                "computer; or use rigd's stitcher (camera.sdk.panorama: rigd)")


class PanoramaBackend(Enum):
    """Who makes a live frame's panorama (``camera.sdk.panorama``)."""

    RIGD_STITCHER = "rigd"  # rigd's stitcher, from the head calibration the sensor images go with
    SDK_RENDERER = "sdk"  # FLIR's renderer (ladybugRenderOffScreenImage), from the calibration loaded in the SDK


class ColorMethod(Enum):
    """The SDK's demosaicing for its renderer's textures (``LadybugColorProcessingMethod`` members at full size)."""

    EDGE_SENSING = "EDGE_SENSING"
    NEAREST_NEIGHBOR_FAST = "NEAREST_NEIGHBOR_FAST"
    RIGOROUS = "RIGOROUS"
    HQLINEAR = "HQLINEAR"


class PanoramaRenderer(Protocol):
    """A panorama backend: one (H, W, 3) uint8 BGR equirectangular image per sensor frame; raises a
    :class:`Ladybug5Error` for a frame that cannot be rendered (a :class:`RendererError` when none can)."""

    def panorama(self, frame: SensorFrame) -> NDArray[np.uint8]: ...


class StitcherBackend:
    """rigd's stitcher: given ready, or built from the first frame's head at ``spec``."""

    def __init__(self, *, spec: PanoramaSpec, stitcher: Stitcher | None = None) -> None:
        self.spec = spec
        self.stitcher = stitcher

    def panorama(self, frame: SensorFrame) -> NDArray[np.uint8]:
        if self.stitcher is None:
            self.stitcher = Stitcher(frame.head.to_rig(), self.spec)
        return self.stitcher.stitch([None if c in frame.missing_cameras else to_uint8(im)
                                     for c, im in enumerate(frame.images)])


class SdkRendererBackend:
    """FLIR's renderer over the camera's own context and its latest grab (``spec``'s width and height; its radius is
    the SDK's own sphere, not set here)."""

    def __init__(self, camera: SdkCamera, *, spec: PanoramaSpec,
                 color_method: ColorMethod = ColorMethod.HQLINEAR) -> None:
        self.camera = camera
        self.size_px = (spec.width, spec.height)
        self.color_method = color_method
        self._configured: int | None = None  # the context configured (a new open is a new context)
        self._textures: list[ctypes.Array[ctypes.c_char]] = []

    def panorama(self, frame: SensorFrame) -> NDArray[np.uint8]:
        context, image = self.camera.sdk_handles("ladybugRenderOffScreenImage")
        grabbed = self.camera.last
        if grabbed is None or grabbed.sequence_id != frame.sequence_id:
            raise Ladybug5Error(f"frame {frame.sequence_id}: the SDK renderer renders only the camera's latest grab "
                                f"({grabbed.sequence_id if grabbed else 'none'})")
        if self._configured != context.value:
            self._configure(context)
        texture_format = self._texture_format(grabbed.data_format)
        pointers = self._texture_pointers(grabbed.full_cols * grabbed.full_rows, texture_format)
        lib = self.camera.lib
        lib.call("ladybugConvertImage", context, image, pointers, lib.layout.pixel_formats[texture_format])
        lib.call("ladybugUpdateTextures", context, CAMERAS, pointers, lib.layout.pixel_formats[texture_format])
        return self._render(context)

    def _configure(self, context: ctypes.c_void_p) -> None:
        lib, (cols, rows) = self.camera.lib, self.size_px
        panoramic = lib.layout.output_images["PANORAMIC"]
        try:
            lib.call("ladybugSetColorProcessingMethod", context, lib.layout.color_methods[self.color_method.value])
            lib.call("ladybugConfigureOutputImages", context, panoramic)
            lib.call("ladybugSetOffScreenImageSize", context, panoramic, cols, rows)
        except Ladybug5Error as exc:
            raise RendererError(f"{self.camera.describe}: cannot set up the SDK's panorama renderer ({exc}); "
                                f"{_OPENGL_HINT}") from exc
        self._configured = context.value

    def _texture_format(self, data_format: int) -> str:
        """BGRU16 textures for data wider than 8 bits (RAW12, RAW16, 12-bit JPEG: ladybugConvertImage's own default for
        them, ladybug.h), BGRU otherwise."""
        formats = self.camera.lib.layout.formats
        wide = {formats[name] for name in ("RAW12", "RAW16", "COLOR_SEP_JPEG12") if name in formats}
        return "BGRU16" if data_format in wide else "BGRU"

    def _texture_pointers(self, full_pixels: int, texture_format: str) -> ctypes.Array[ctypes.c_void_p]:
        """Six texture buffers of the sensors' full size (an upper bound of what ladybugConvertImage writes)."""
        size = full_pixels * (8 if texture_format == "BGRU16" else 4)
        if len(self._textures) != CAMERAS or len(self._textures[0]) != size:
            self._textures = [ctypes.create_string_buffer(size) for _ in range(CAMERAS)]
        return (ctypes.c_void_p * CAMERAS)(*[ctypes.addressof(t) for t in self._textures])

    def _render(self, context: ctypes.c_void_p) -> NDArray[np.uint8]:
        lib, (cols, rows) = self.camera.lib, self.size_px
        processed = lib.new_processed_buffer()
        lib.call("ladybugRenderOffScreenImage", context, lib.layout.output_images["PANORAMIC"],
                 lib.layout.pixel_formats["BGR"], processed)
        image = lib.read_processed(processed, bytes_per_pixel=_BGR_BYTES)
        if (image.cols, image.rows) != (cols, rows) or image.pixel_format != lib.layout.pixel_formats["BGR"]:
            raise CorruptFrameError(f"ladybugRenderOffScreenImage returned {image.cols}x{image.rows} in pixel format "
                                    f"{image.pixel_format:#x}, asked for {cols}x{rows} BGR")
        return np.frombuffer(bytearray(image.data), np.uint8).reshape(rows, cols, _BGR_BYTES)


def panorama_renderer(backend: PanoramaBackend, camera: SdkCamera, *, spec: PanoramaSpec,
                      stitcher: Stitcher | None = None) -> StitcherBackend | SdkRendererBackend:
    """The backend ``backend`` names, for ``camera``'s frames at ``spec``'s size."""
    if backend is PanoramaBackend.SDK_RENDERER:
        return SdkRendererBackend(camera, spec=spec)
    return StitcherBackend(spec=spec, stitcher=stitcher)
