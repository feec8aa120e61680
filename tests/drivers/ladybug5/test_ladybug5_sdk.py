"""The ctypes SDK binding against a fake libladybug built here with the system C compiler.

The fake (fake_sdk/) has the SDK's function and member names but its own struct layout and enum values;
the binding gets those through layout_probe.c compiled against the fake header, exactly as it would
against FLIR's ladybug.h.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ladybug5_helpers import scaled_rig

from drivers.ladybug5.errors import (
    CameraNotFoundError,
    InterfaceSpeedError,
    Ladybug5Error,
    LibraryMissingError,
    MissingPowerError,
    SdkError,
)
from drivers.ladybug5.pgr import DEFAULT_LAYOUT, PgrFrameData, PgrStream, bayer_planes, write_pgr
from drivers.ladybug5.rig import RigCamera, RigCameras, default_ladybug5_rig
from drivers.ladybug5.sdk import (
    DataFormat,
    DeviceTimeField,
    LadybugLibrary,
    SdkCamera,
    SdkFrameSource,
    decode_grab,
    probe_layout,
    sdk_status,
)
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher

FAKE = Path(__file__).resolve().parent / "fake_sdk"
COMPILER = shutil.which("gcc") or shutil.which("cc")
pytestmark = pytest.mark.skipif(COMPILER is None, reason="no C compiler (gcc/cc) to build the fake Ladybug SDK")
COLS, ROWS = 16, 12  # the fake's camera images


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(library path, probed layout); one build per module, a fresh library copy per test below."""
    out = tmp_path_factory.mktemp("fake_sdk")
    lib = out / "libfakeladybug.so"
    subprocess.run(
        [COMPILER, "-shared", "-fPIC", "-o", str(lib), "-I", str(FAKE), str(FAKE / "fake_ladybug.c")], check=True
    )
    return lib, probe_layout(FAKE, compiler=COMPILER, out=out / "layout.yaml")


@pytest.fixture
def fake(built, tmp_path):
    """A private copy of the fake library (its globals start fresh) and its ctypes handle to steer it."""
    lib_path = tmp_path / "libfakeladybug.so"
    shutil.copy(built[0], lib_path)
    library = LadybugLibrary(built[1], lib_path)
    handle = ctypes.CDLL(str(lib_path))  # same path: dlopen returns the same instance
    return library, handle


def g(handle, name):
    return ctypes.c_int.in_dll(handle, name)


def tiny_rig() -> RigCameras:
    """The default head with the fake's 16x12 px images."""
    base = scaled_rig(default_ladybug5_rig(), COLS / 2448)
    cams = [RigCamera(c.name, COLS, ROWS, c.K, c.D, c.R_head_camera, c.t_head_camera_m) for c in base.cameras]
    return RigCameras("tiny", tuple(cams))


def test_probe_reads_the_fake_headers_own_numbers(built):
    layout = built[1]
    # Values from fake_sdk/ladybug.h, which differ on purpose from any real SDK's.
    assert layout.errors["BAD_VOLTAGE"] == 110 and layout.formats["RAW8"] == 21
    assert layout.properties == {"SHUTTER": 31, "GAIN": 32}
    assert layout.image_fields["cycle_seconds"][1] == 8 and layout.image_fields["cycle_count"][1] == 2


def test_missing_library_says_so(built, tmp_path):
    with pytest.raises(LibraryMissingError, match="FLIR's Ladybug SDK"):
        LadybugLibrary(built[1], tmp_path / "libladybug.so")
    assert "not available" in sdk_status(tmp_path / "libladybug.so")
    with pytest.raises(LibraryMissingError, match="lacks ladybugCreateContext"):
        LadybugLibrary(built[1], ctypes.util.find_library("m") or "libm.so.6")


def test_lifecycle_grab_and_raw8_decoding(fake):
    library, handle = fake
    camera = SdkCamera(library, data_format=DataFormat.RAW8)
    with camera:
        assert camera.enumerate_serials() == [17092345]
        grabbed = [camera.grab() for _ in range(3)]
        exposure = camera.exposure()
    assert (g(handle, "fake_started").value, g(handle, "fake_stopped").value, g(handle, "fake_destroyed").value) == (
        1,
        1,
        1,
    )
    assert (ctypes.c_char * 256).in_dll(handle, "fake_config_path").value == b"(from head)"
    assert [im.sequence_id for im in grabbed] == [1000, 1001, 1002]
    assert [(im.cols, im.rows) for im in grabbed] == [(COLS, ROWS)] * 3
    # Cycle time: 1020 ticks of 125 us = 127.5 s, then +0.1 s a frame, wrapping at 128 s.
    np.testing.assert_allclose([im.cycle_time_s for im in grabbed], [127.5, 127.6, 127.7], atol=1e-9)
    assert grabbed[1].embedded_time_s == pytest.approx(1700000001.25)
    assert len(grabbed[0].data) == 6 * COLS * ROWS and grabbed[2].data[COLS * ROWS * 5] == 40 * 5 + 2
    assert exposure.shutter_s == pytest.approx(2.5e-3) and exposure.gain_db == pytest.approx(6.0)


def test_error_codes_map_to_named_errors(fake):
    library, handle = fake
    codes = library.layout.errors
    g(handle, "fake_init_error").value = codes["BAD_VOLTAGE"]
    with pytest.raises(MissingPowerError, match="12-24 V"):
        SdkCamera(library).open()
    g(handle, "fake_init_error").value = codes["BAD_INTERFACE"]
    with pytest.raises(InterfaceSpeedError, match="SuperSpeed"):
        SdkCamera(library).open()
    g(handle, "fake_init_error").value = 0
    with pytest.raises(CameraNotFoundError, match="fake Ladybug error 101"):
        SdkCamera(library, index=3).open()
    # Every failed open still destroyed its context.
    assert g(handle, "fake_destroyed").value == g(handle, "fake_contexts").value == 3
    with pytest.raises(Ladybug5Error, match="not open"):
        SdkCamera(library).grab()  # never hands the SDK a null context


def test_frame_source_skips_corrupt_frames_maps_time_and_stops_on_timeouts(fake):
    library, handle = fake
    g(handle, "fake_bad_frame").value = 2
    g(handle, "fake_timeout_from").value = 8
    source = SdkFrameSource(
        SdkCamera(library, data_format=DataFormat.RAW8),
        Stitcher(tiny_rig(), PanoramaSpec(64, 32, math.inf)),
        max_consecutive_failures=3,
    )
    frames = []
    with pytest.raises(SdkError, match="error 103"):
        for frame in source.frames():
            frames.append(frame)
    assert [f.sequence_id for f in frames] == [1000, 1001, 1003, 1004, 1005, 1006, 1007]
    assert source.skipped.count == 1
    # Unwrapped across the 128 s wrap after frame 4.
    np.testing.assert_allclose([f.device_time_s for f in frames], 127.5 + 0.1 * np.array([0, 1, 3, 4, 5, 6, 7]))
    offset = source.clock.report().offset_s
    assert all(f.host_time_s == pytest.approx(f.device_time_s + offset) for f in frames)
    assert frames[0].image.shape == (32, 64, 3)
    assert g(handle, "fake_stopped").value == 1 and g(handle, "fake_destroyed").value == 1


def test_color_sep_jpeg_buffers_decode_like_pgr_frames(fake, tmp_path):
    library, handle = fake
    rng = np.random.default_rng(0)
    image = np.clip(rng.normal(128, 20, (ROWS, COLS, 3)), 0, 255).astype(np.uint8)
    frame = PgrFrameData(5, 0, 1, [bayer_planes(image, DEFAULT_LAYOUT)] * 6)
    write_pgr(tmp_path / "one.pgr", [frame])
    stream = PgrStream(tmp_path / "one.pgr")
    entry = stream.index[0]
    (tmp_path / "block.bin").write_bytes(stream._buf[entry.offset : entry.offset + entry.size])
    assert handle.fake_load_block(str(tmp_path / "block.bin").encode()) == 0
    with SdkCamera(library, data_format=DataFormat.COLOR_SEP_JPEG8) as camera:
        decoded = decode_grab(camera.grab(), library.layout, "BGGR", DEFAULT_LAYOUT)
    for got, want in zip(decoded, stream.camera_images(0), strict=True):
        np.testing.assert_array_equal(got, want)  # same bytes through ctypes as read from the file
    source = SdkFrameSource(
        SdkCamera(library, data_format=DataFormat.COLOR_SEP_JPEG8),
        Stitcher(tiny_rig(), PanoramaSpec(64, 32, math.inf)),
        time_field=DeviceTimeField.EMBEDDED,
    )
    frames = source.frames()
    first = next(frames)
    frames.close()  # stopping the iteration stops and destroys the camera
    assert first.device_time_s == pytest.approx(1700000000.25)
    assert first.time_base.value == "gps"
    assert g(handle, "fake_stopped").value == 2 and g(handle, "fake_destroyed").value == 2
