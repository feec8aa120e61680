"""The SDK's panorama renderer as a backend of SdkFrameSource, through the real ctypes path into the fake libladybug.

The fake (fake_sdk/fake_ladybug.c) fills each camera's texture with its flat colour and renders the six textures side
by side, camera c in the c-th sixth of the columns; it logs the renderer calls in order (M method, C configure,
S panoramic size, V convert, U update textures, R render).
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np
import pytest
import yaml
from fake_ladybug_sdk import COMPILER, Fake, build

from drivers.ladybug5.errors import RendererError
from drivers.ladybug5.formats import DataFormat
from drivers.ladybug5.sdk import SdkCamera
from drivers.ladybug5.sdk_render import PanoramaBackend
from drivers.ladybug5.sdk_source import HeadPolicy, SdkFrameSource
from drivers.ladybug5.stitch import PanoramaSpec
from rigd.capture.config import load_settings
from rigd.capture.errors import ConfigError

pytestmark = pytest.mark.skipif(COMPILER is None, reason="no C compiler (gcc/cc) to build the fake Ladybug SDK")
PANO = PanoramaSpec(60, 30)  # ten columns per camera
PANORAMA = {"model": "equirectangular", "width": 64, "height": 32}


def render_log(fake: Fake) -> str:
    return (ctypes.c_char * 256).in_dll(fake.handle, "fake_render_log").value.decode()


def rendered_source(fake: Fake, fmt: DataFormat = DataFormat.RAW8, **kwargs: int) -> SdkFrameSource:
    return SdkFrameSource(SdkCamera(fake.library, data_format=fmt), PANO, head=HeadPolicy.NOMINAL,
                          panorama=PanoramaBackend.SDK_RENDERER, **kwargs)


def take(source: SdkFrameSource, n: int) -> list:
    stream = source.frames()
    frames = [next(stream) for _ in range(n)]
    stream.close()
    return frames


def strip_colours(image: np.ndarray) -> list[tuple[int, ...]]:
    """The one colour of each camera's sixth of the columns (fails if a strip is not flat)."""
    strips = np.split(image, 6, axis=1)
    assert all(np.all(s == s[0, 0]) for s in strips)
    return [tuple(int(v) for v in s[0, 0]) for s in strips]


def test_the_probe_measures_the_processed_image_and_the_renderers_enums(built, tmp_path):
    layout = built[1]
    assert layout.output_images["PANORAMIC"] == 0x1000 and layout.pixel_formats["BGR"] == 0x10000001
    assert layout.pixel_formats["BGRU"] == 0x10000002 and layout.color_methods["HQLINEAR"] == 7
    fields = layout.processed_image_fields
    assert fields["cols"][0] < fields["rows"][0] < fields["data"][0] < fields["pixel_format"][0]
    assert fields["data"][1] == ctypes.sizeof(ctypes.c_void_p) and layout.processed_image_size > 256
    shifted = build(tmp_path, 40)[1]  # every renderer number comes from the probe too
    assert shifted.pixel_formats["BGR"] == 0x10000001 + 40 and shifted.color_methods["HQLINEAR"] == 47


@pytest.mark.parametrize("fmt, texture", [(DataFormat.RAW8, "BGRU"), (DataFormat.RAW16, "BGRU16")])
def test_the_sdk_renders_each_frames_panorama_in_order(fake, fmt, texture):
    source = rendered_source(fake, fmt)
    frames = take(source, 3)
    layout = fake.library.layout
    assert render_log(fake) == "MCS" + "VUR" * 3  # configured once, before the first render; textures every frame
    assert (fake.g("fake_pano_cols").value, fake.g("fake_pano_rows").value) == (60, 30)
    assert fake.g("fake_configured").value == layout.output_images["PANORAMIC"]
    assert fake.g("fake_color_method").value == layout.color_methods["HQLINEAR"]
    assert fake.g("fake_texture_format").value == layout.pixel_formats[texture]
    for k, frame in enumerate(frames):
        assert frame.image.shape == (30, 60, 3) and frame.image.dtype == np.uint8
        # Camera c's colour in the c-th strip, with this frame's green: the textures were updated from this grab.
        assert strip_colours(frame.image) == [(20 + 30 * c, 100 + k, 220 - 20 * c) for c in range(6)]
    assert [f.sequence_id for f in frames] == [1000, 1001, 1002] and source.stitcher is None
    assert source.skipped.count == 0 and fake.g("fake_destroyed").value == 1


def test_a_failed_render_ends_the_frame_not_the_stream(fake):
    fake.set(render_error_at=1)
    source = rendered_source(fake)
    frames = take(source, 3)
    assert [f.sequence_id for f in frames] == [1000, 1002, 1003] and source.skipped.count == 1
    # LADYBUG_GPU_ERROR (50 in the 2017 header), named with the call and the SDK's text
    assert "ladybugRenderOffScreenImage failed with Ladybug error 50 (fake Ladybug error 50)" in \
        source.skipped.reasons[0]
    assert strip_colours(frames[1].image)[0] == (20, 102, 220)


def test_a_renderer_without_opengl_ends_the_stream_at_once(fake):
    fake.set(configure_error=1)  # LADYBUG_FAILED, as from a computer without an OpenGL context
    source = rendered_source(fake)
    with pytest.raises(RendererError, match=r"ladybugConfigureOutputImages failed.*OpenGL.*camera.sdk.panorama: rigd"):
        list(source.frames())
    assert source.skipped.count == 0 and render_log(fake) == "MC"  # no render was attempted
    assert fake.g("fake_destroyed").value == 1


def test_the_panorama_backend_setting(tmp_path: Path):
    path = tmp_path / "rig.yaml"
    assert load_settings(None).sdk.panorama is PanoramaBackend.RIGD_STITCHER
    path.write_text(yaml.safe_dump({"camera": {**PANORAMA, "sdk": {"panorama": "sdk"}}}))
    assert load_settings(path).sdk.panorama is PanoramaBackend.SDK_RENDERER
    path.write_text(yaml.safe_dump({"camera": {**PANORAMA, "sdk": {"panorama": "opengl"}}}))
    with pytest.raises(ConfigError, match=r"camera.sdk.panorama: must be one of rigd, sdk, got 'opengl'"):
        load_settings(path)
