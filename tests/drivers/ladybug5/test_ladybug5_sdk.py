"""The ctypes SDK binding against a fake libladybug built here with the system C compiler.

The fake (fake_sdk/) declares the real SDK's structs member for member (so the border, full size and Bayer
pattern sit where a real camera's are) and its functions; it serves frames with a border of masked pixels and
each Bayer pattern, and a lens model for the head calibration. A second build shifts every enum value, which
the binding must take from layout_probe.c like any other SDK number.
"""

from __future__ import annotations

import ctypes.util
import math

import numpy as np
import pytest
from fake_ladybug_sdk import BORDER, COLS, COMPILER, ROWS, build, private_copy
from ladybug5_helpers import BLUE, RED, documented_channel_jpegs, scaled_rig

from drivers.ladybug5.errors import (
    CameraNotFoundError,
    CorruptFrameError,
    HeadCalibrationError,
    InterfaceSpeedError,
    Ladybug5Error,
    LibraryMissingError,
    MissingPowerError,
    SdkError,
    UnsupportedFormatError,
)
from drivers.ladybug5.formats import STREAM_BAYER_CODES, STREAM_FORMAT_CODES, BayerPattern, DataFormat
from drivers.ladybug5.head import HeadSource
from drivers.ladybug5.pgr import PgrFrameData, PgrStream, PgrWriteOptions, bayer_planes, write_pgr
from drivers.ladybug5.raw import Border
from drivers.ladybug5.rig import RigCamera, RigCameras, default_ladybug5_rig
from drivers.ladybug5.sdk import (
    DeviceTimeField,
    GrabbedImage,
    LadybugLibrary,
    SdkCamera,
    decode_grab,
    enumerate_cameras,
    frame_pattern,
    sdk_status,
)
from drivers.ladybug5.sdk_head import LensSource, head_from_pgr
from drivers.ladybug5.sdk_source import HeadPolicy, SdkFrameSource, SdkSensorSource
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher

pytestmark = pytest.mark.skipif(COMPILER is None, reason="no C compiler (gcc/cc) to build the fake Ladybug SDK")
SHIFT = 40


def tiny_rig(cols: int = COLS, rows: int = ROWS) -> RigCameras:
    """The default head with the fake's small images."""
    base = scaled_rig(default_ladybug5_rig(), cols / 2448)
    cams = [RigCamera(c.name, cols, rows, c.K, c.D, c.R_head_camera, c.t_head_camera_m) for c in base.cameras]
    return RigCameras("tiny", tuple(cams))


def expected_colour(camera: int, frame: int) -> tuple[int, int, int]:
    """The fake's flat (B, G, R) inside the border (fake_ladybug.c)."""
    return 20 + 30 * camera, 100 + frame, 220 - 20 * camera


def test_probe_reads_the_real_layouts_numbers(built):
    layout = built[1]
    assert layout.errors["BAD_VOLTAGE"] == 58 and layout.errors["TIMEOUT"] == 20 and layout.formats["RAW8"] == 1
    # A .pgr stores the SDK's values: rigd's tables for stream files agree with the header's enums.
    assert {code: fmt.value for code, fmt in STREAM_FORMAT_CODES.items()} == {v: k for k, v in layout.formats.items()}
    assert {code: (p.value if p else "DEFAULT") for code, p in STREAM_BAYER_CODES.items()} == {
        v: k for k, v in layout.stippled.items()}
    fields = layout.image_fields
    assert fields["full_cols"][0] > fields["border_right"][0] > fields["cols"][0]  # the real member order
    assert layout.camera_info_fields["model_name"][1] == 256


def test_every_number_comes_from_the_probe(tmp_path):
    shifted = build(tmp_path, SHIFT)
    assert shifted[1].formats["RAW8"] == 1 + SHIFT and shifted[1].stippled["BGGR"] == SHIFT
    (tmp_path / "copy").mkdir()
    fake = private_copy(shifted, tmp_path / "copy")
    with SdkCamera(fake.library, data_format=DataFormat.RAW8) as camera:
        image = camera.grab()
        decoded = decode_grab(image, fake.library.layout, frame_pattern(image, fake.library, camera.tile_pattern))
    assert np.all(decoded[2] == expected_colour(2, 0))


def test_missing_library_says_so(built, tmp_path):
    with pytest.raises(LibraryMissingError, match="FLIR's Ladybug SDK"):
        LadybugLibrary(built[1], tmp_path / "libladybug.so")
    assert "not available" in sdk_status(tmp_path / "libladybug.so")
    with pytest.raises(LibraryMissingError, match="lacks ladybugCreateContext"):
        LadybugLibrary(built[1], ctypes.util.find_library("m") or "libm.so.6")


def test_cameras_are_enumerated_before_initialising_and_opened_by_serial(fake):
    fake.set(cameras=2)
    assert [(c.serial, c.model) for c in enumerate_cameras(fake.library)] == [
        (17092345, "Ladybug5+ (fake 0)"), (17092346, "Ladybug5+ (fake 1)")]
    with pytest.raises(CameraNotFoundError, match=r"2 cameras \(17092345, 17092346\).*--serial"):
        SdkCamera(fake.library).open()
    with pytest.raises(CameraNotFoundError, match="17000000 is not on the bus; the SDK sees 17092345, 17092346"):
        SdkCamera(fake.library, serial=17000000).open()
    with SdkCamera(fake.library, serial=17092346, data_format=DataFormat.RAW8) as camera:
        assert camera.describe == "camera 17092346 (Ladybug5+ (fake 1))"
    assert fake.g("fake_initialized_serial").value == 17092346 and fake.g("fake_enumerated_before_init").value == 1
    assert fake.g("fake_destroyed").value == fake.g("fake_contexts").value


def test_lifecycle_timeout_and_the_grabbed_fields(fake):
    camera = SdkCamera(fake.library, data_format=DataFormat.RAW8, grab_timeout_ms=750)
    with camera:
        grabbed = [camera.grab() for _ in range(3)]
        exposure = camera.exposure()
    assert (fake.g("fake_started").value, fake.g("fake_stopped").value, fake.g("fake_destroyed").value) == (1, 1, 1)
    assert fake.g("fake_grab_timeout").value == 750 and fake.g("fake_timeout_set_after_start").value == 0
    assert (ctypes.c_char * 256).in_dll(fake.handle, "fake_config_path").value == b"(from head)"
    first = grabbed[0]
    top, bottom, left, right = BORDER
    assert (first.cols, first.rows, first.full_cols, first.full_rows) == (COLS, ROWS, COLS + left + right,
                                                                          ROWS + top + bottom)
    assert first.border == Border(*BORDER) and first.stippled_format == fake.library.layout.stippled["RGGB"]
    assert [im.sequence_id for im in grabbed] == [1000, 1001, 1002]
    np.testing.assert_allclose([im.cycle_time_s for im in grabbed], [127.5, 127.6, 127.7], atol=1e-9)
    assert grabbed[1].embedded_time_s == pytest.approx(1700000001.25)
    assert len(first.data) == 6 * first.full_cols * first.full_rows
    assert exposure.shutter_s == pytest.approx(2.5e-3) and exposure.gain_db == pytest.approx(6.0)


@pytest.mark.parametrize("fmt", [DataFormat.RAW8, DataFormat.RAW16])
@pytest.mark.parametrize("pattern", list(BayerPattern))
def test_raw_frames_are_sliced_by_the_full_size_cropped_and_debayered_with_the_sdks_pattern(fake, fmt, pattern):
    fake.set(stippled=fake.library.layout.stippled[pattern.value], tile=fake.library.layout.stippled["DEFAULT"])
    with SdkCamera(fake.library, data_format=fmt) as camera:
        image = camera.grab()
        decoded = decode_grab(image, fake.library.layout, frame_pattern(image, fake.library, camera.tile_pattern))
    scale = 256 if fmt is DataFormat.RAW16 else 1
    for cam, got in enumerate(decoded):
        assert got.shape == (ROWS, COLS, 3) and got.dtype == (np.uint16 if scale > 1 else np.uint8)
        # Exactly the flat colour: no masked pixel, no row shear, red and blue where they belong.
        assert np.all(got == np.array(expected_colour(cam, 0)) * scale), (cam, np.unique(got.reshape(-1, 3), axis=0))


def test_the_colour_tile_format_stands_in_when_the_image_says_default(fake):
    layout = fake.library.layout
    fake.set(stippled=layout.stippled["DEFAULT"], tile=layout.stippled["GBRG"])
    with SdkCamera(fake.library, data_format=DataFormat.RAW8) as camera:
        assert camera.tile_pattern is BayerPattern.GBRG
        image = camera.grab()
        assert frame_pattern(image, fake.library, camera.tile_pattern) is BayerPattern.GBRG
        decoded = decode_grab(image, layout, BayerPattern.GBRG)
        assert np.all(decoded[0] == expected_colour(0, 0))
    with pytest.raises(Ladybug5Error, match="no Bayer pattern"):
        frame_pattern(image, fake.library, None)


def test_error_codes_map_to_named_errors(fake):
    codes = fake.library.layout.errors
    fake.set(init_error=codes["BAD_VOLTAGE"])
    with pytest.raises(MissingPowerError, match="12-24 V"):
        SdkCamera(fake.library).open()
    fake.set(init_error=codes["BAD_INTERFACE"])
    with pytest.raises(InterfaceSpeedError, match="SuperSpeed"):
        SdkCamera(fake.library).open()
    fake.set(init_error=1)
    with pytest.raises(CameraNotFoundError, match="cannot open camera 17092345.*fake Ladybug error 1"):
        SdkCamera(fake.library).open()
    fake.set(init_error=0, cameras=0)
    with pytest.raises(CameraNotFoundError, match="sees no camera on the bus"):
        SdkCamera(fake.library).open()
    # Every failed open still destroyed its context.
    assert fake.g("fake_destroyed").value == fake.g("fake_contexts").value == 4
    with pytest.raises(Ladybug5Error, match="not open"):
        SdkCamera(fake.library).grab()  # never hands the SDK a null context


def test_unsupported_formats_are_named_not_corrupt(fake):
    with pytest.raises(UnsupportedFormatError, match="HALF_HEIGHT_RAW16 is not supported.*row layout is not public"):
        SdkCamera(fake.library, data_format=DataFormat.HALF_HEIGHT_RAW16)
    layout = fake.library.layout
    image = GrabbedImage(COLS, ROWS, COLS, ROWS, Border(), layout.formats["HALF_HEIGHT_RAW12"],
                         layout.stippled["RGGB"], 0.0, 0.0, 7, b"\0" * 1000, 0.0)
    with pytest.raises(UnsupportedFormatError, match="grabbed frame 7: data format HALF_HEIGHT_RAW12 is not supported"):
        decode_grab(image, layout, BayerPattern.RGGB)


def test_frame_source_skips_failures_maps_time_and_stops_on_timeouts(fake):
    fake.set(bad_frame=2, timeout_from=8)
    source = SdkFrameSource(SdkCamera(fake.library, data_format=DataFormat.RAW8),
                            Stitcher(tiny_rig(), PanoramaSpec(64, 32, math.inf)), max_consecutive_failures=3)
    frames = []
    with pytest.raises(SdkError, match=f"error {fake.library.layout.errors['TIMEOUT']}"):
        for frame in source.frames():
            frames.append(frame)
    assert [f.sequence_id for f in frames] == [1000, 1001, 1003, 1004, 1005, 1006, 1007]
    jpeg_error = f"Ladybug error {fake.library.layout.errors['JPEG_ERROR']}"
    assert source.skipped.count == 1 + 3 and jpeg_error in source.skipped.reasons[0]  # the bad frame, then timeouts
    # Unwrapped across the 128 s wrap after frame 4.
    np.testing.assert_allclose([f.device_time_s for f in frames], 127.5 + 0.1 * np.array([0, 1, 3, 4, 5, 6, 7]))
    offset = source.clock.report().offset_s
    assert all(f.host_time_s == pytest.approx(f.device_time_s + offset) for f in frames)
    assert frames[0].image.shape == (32, 64, 3)
    assert fake.g("fake_stopped").value == 1 and fake.g("fake_destroyed").value == 1


def test_a_stitch_error_ends_a_frame_not_the_stream(fake):
    stitcher = Stitcher(tiny_rig(), PanoramaSpec(64, 32, math.inf))
    real = stitcher.stitch
    calls = []

    def flaky(images):
        calls.append(1)
        if len(calls) == 2:
            raise Ladybug5Error("cam3: image is 5x5, rig file says 16x12")
        return real(images)

    stitcher.stitch = flaky  # type: ignore[method-assign]
    source = SdkFrameSource(SdkCamera(fake.library, data_format=DataFormat.RAW8), stitcher,
                            max_consecutive_failures=2)
    stream = source.frames()
    got = [next(stream).sequence_id for _ in range(3)]
    stream.close()
    assert got == [1000, 1002, 1003] and source.skipped.count == 1 and "cam3" in source.skipped.reasons[0]
    def never(images):
        raise Ladybug5Error("cam0: no")

    broken = Stitcher(tiny_rig(), PanoramaSpec(64, 32, math.inf))
    broken.stitch = never  # type: ignore[method-assign]
    always = SdkFrameSource(SdkCamera(fake.library, data_format=DataFormat.RAW8), broken, max_consecutive_failures=3)
    with pytest.raises(Ladybug5Error, match="cam0: no"):
        list(always.frames())
    assert always.skipped.count == 3  # three in a row end the stream


def test_a_head_that_does_not_fit_the_camera_is_a_clear_error(fake):
    wrong = SdkFrameSource(SdkCamera(fake.library, data_format=DataFormat.RAW8),
                           Stitcher(tiny_rig(COLS + 2), PanoramaSpec(64, 32, math.inf)))
    with pytest.raises(HeadCalibrationError, match=r"is for sensors \[\(18, 12\)\], the camera sends \[\(16, 12\)\]"):
        list(wrong.frames())
    assert fake.g("fake_destroyed").value == 1


def test_exposure_read_failures_do_not_end_the_stream(fake):
    fake.set(exposure_error=1)
    source = SdkSensorSource(SdkCamera(fake.library, data_format=DataFormat.RAW8), HeadPolicy.NOMINAL)
    stream = source.frames()
    frames = [next(stream) for _ in range(2)]
    stream.close()
    assert [f.exposure.shutter_s for f in frames] == [None, None] and source.skipped.count == 0
    assert source.exposure_errors.count == 2 and "ladybugGetAbsProperty" in source.exposure_errors.reasons[0]


def test_the_factory_head_is_read_through_the_sdk(fake):
    with SdkCamera(fake.library, data_format=DataFormat.RAW8) as camera:
        head = camera.read_head((COLS, ROWS), step_px=2)
    assert fake.g("fake_rect_cols").value == COLS and fake.g("fake_rect_rows").value == ROWS
    assert head.source is HeadSource.FACTORY and head.serial == 17092345 and "ladybugLoadConfig" in head.description
    for cam, sensor in enumerate(head.sensors):
        k, d = fake.lens(cam)
        np.testing.assert_allclose(sensor.lens.K, k, atol=1e-6)
        np.testing.assert_allclose(sensor.lens.D, d, atol=1e-6)
        assert sensor.lens.rms_px < 1e-6 and not sensor.lens.poor
        assert sensor.maps is not None and sensor.maps.raw_to_rect.shape == (7, 9, 2)
        np.testing.assert_allclose(sensor.R_head_camera, craig_matrix(*sensor.extrinsics[:3]), atol=1e-12)
    side = head.sensors[1]
    yaw = np.radians(72.0)
    np.testing.assert_allclose(side.extrinsics, [0.01, np.pi / 2, yaw, 0.045 * np.cos(yaw), 0.045 * np.sin(yaw), 0])
    np.testing.assert_allclose(side.t_head_camera_m, 0.045 * np.array([np.cos(yaw), np.sin(yaw), 0.0]), atol=1e-12)
    assert side.R_head_camera[:, 2] @ [np.cos(yaw), np.sin(yaw), 0.0] > 0.999  # its optical axis looks out


def test_the_lens_fit_lands_on_the_raw_lens_from_a_real_units_rectified_focal_length(fake):
    """A real Ladybug5's SDK reports a rectified focal length of about 450 px at 2448x2048 while the raw lens is about
    1275 px (docs/ladybug5.md): the fit starts at the rectified one and must still find the raw one."""
    raw_focal, k1, k2 = 4.4e-3 / 3.45e-6, -0.2, 0.03
    fake.set(cols=2448, rows=2048)
    fake.set_double(focal=raw_focal, k1=k1, k2=k2, rect_focal_scale=452.0 / raw_focal)
    with SdkCamera(fake.library, data_format=DataFormat.RAW8) as camera:
        head = camera.read_head((2448, 2048), step_px=128)  # 20 x 17 points a sensor: enough for 9 parameters
    for cam, sensor in enumerate(head.sensors):
        assert sensor.focal_px == pytest.approx(452.0)
        k, d = fake.lens(cam, 2448, 2048)
        np.testing.assert_allclose(sensor.lens.K, k, atol=1e-4)
        np.testing.assert_allclose(sensor.lens.D, d, atol=1e-7)
        assert sensor.lens.rms_px < 1e-4 and not sensor.lens.poor


def test_the_rectified_images_are_configured_before_their_size_and_geometry(fake):
    fake.set(size_needs_configure=1)  # the fake takes the rectified size only for configured rectified images
    with SdkCamera(fake.library, data_format=DataFormat.RAW8) as camera:
        head = camera.read_head((COLS, ROWS), step_px=2)
    assert fake.call_log() == "CS" + "F" * 6  # configure, size, then each sensor's geometry
    assert fake.g("fake_configured").value == fake.library.layout.output_images["ALL_RECTIFIED_IMAGES"]
    assert head.sensors[0].focal_px == pytest.approx(10.0)


def test_a_refused_configuration_is_logged_and_the_geometry_read_anyway(fake, caplog):
    fake.set(configure_error=1)  # LADYBUG_FAILED, as perhaps on a rig without OpenGL
    with SdkCamera(fake.library, data_format=DataFormat.RAW8) as camera:
        # This SDK gives the geometry without the configuration: a warning, no error.
        assert camera.read_head((COLS, ROWS), step_px=2).sensors[5].focal_px == pytest.approx(10.0)
        assert "ladybugConfigureOutputImages failed with Ladybug error 1" in caplog.text
        fake.set(size_needs_configure=1, rect_cols=0)  # an SDK that needs it, and no size set yet
        with pytest.raises(HeadCalibrationError, match=r"ladybugGetCameraUnitFocalLength failed with Ladybug error "
                           r"\d+ .*\(after ladybugConfigureOutputImages failed with Ladybug error 1"):
            camera.read_head((COLS, ROWS), step_px=2, lens=LensSource.RECTIFIED)


def test_a_headless_rig_reads_the_lens_from_the_3d_map(fake, caplog):
    """Every renderer call refused (no OpenGL context): the lens comes from ladybugGet3dMap, the same lens the
    rectification gives, with the SDK's sphere size and mesh rotation as they were."""
    fake.set_double(sphere=20.0, map_rx=0.002, map_ry=-0.001, map_rz=0.0)  # a factory levelling of the mesh
    with SdkCamera(fake.library, data_format=DataFormat.RAW8) as camera:
        rectified = camera.read_head((COLS, ROWS), step_px=1)
        fake.set(headless=1)
        head = camera.read_head((COLS, ROWS), step_px=1)
    assert "INVALID_OPENGL_RENDERING_CONTEXT" in caplog.text or "ladybugSetOffScreenImageSize failed" in caplog.text
    assert "lens from ladybugGet3dMap" in head.description and head.source is HeadSource.FACTORY
    for cam, (a, b) in enumerate(zip(rectified.sensors, head.sensors, strict=True)):
        k, d = fake.lens(cam)
        np.testing.assert_allclose(b.lens.K, k, atol=2e-3)
        np.testing.assert_allclose(b.lens.D, d, atol=2e-4)
        assert b.lens.rms_px < 1e-3 and b.maps is None and np.isnan(b.focal_px)
        assert b.extrinsics == a.extrinsics
    values = [ctypes.c_double.in_dll(fake.handle, f"fake_{n}").value for n in ("sphere", "map_rx", "map_ry")]
    assert values == [20.0, 0.002, -0.001]  # put back


def test_a_headless_rig_without_a_3d_map_says_why_and_what_to_do(fake):
    fake.set(headless=1, map_error=1)
    with SdkCamera(fake.library, data_format=DataFormat.RAW8) as camera, pytest.raises(
            HeadCalibrationError, match=r"the rectified geometry failed \(.*ladybugSetOffScreenImageSize failed .*"
            r"ladybugGet3dMap failed with Ladybug error 1.*software renderer is not for Ladybug3 or newer.*xvfb-run"):
        camera.read_head((COLS, ROWS), step_px=2)


def craig_matrix(rx: float, ry: float, rz: float) -> np.ndarray:
    """The rotation ladybuggeom.h documents for ladybugGetCameraUnitExtrinsics, element by element."""
    s, c = np.sin, np.cos
    return np.array([
        [c(rz) * c(ry), c(rz) * s(ry) * s(rx) - s(rz) * c(rx), c(rz) * s(ry) * c(rx) + s(rz) * s(rx)],
        [s(rz) * c(ry), s(rz) * s(ry) * s(rx) + c(rz) * c(rx), s(rz) * s(ry) * c(rx) - c(rz) * s(rx)],
        [-s(ry), c(ry) * s(rx), c(ry) * c(rx)],
    ])


def test_the_sensor_source_yields_raw_images_with_the_factory_head(fake):
    source = SdkSensorSource(SdkCamera(fake.library, data_format=DataFormat.RAW16), map_step_px=2,
                             time_field=DeviceTimeField.EMBEDDED)
    stream = source.frames()
    first, second = next(stream), next(stream)
    stream.close()
    assert len(first.images) == 6 and all(im.shape == (ROWS, COLS, 3) for im in first.images)
    assert np.all(first.images[4] == np.array(expected_colour(4, 0)) * 256)
    assert first.head is second.head and first.head.source is HeadSource.FACTORY
    assert first.device_time_s == pytest.approx(1700000000.25) and first.time_base.value == "gps"
    assert first.exposure.gain_db == pytest.approx(6.0)
    assert fake.g("fake_destroyed").value == 1


def test_panoramas_stitched_from_the_factory_head(fake):
    source = SdkFrameSource(SdkCamera(fake.library, data_format=DataFormat.RAW8), PanoramaSpec(64, 32, math.inf))
    source.sensors.map_step_px = 2
    stream = source.frames_with_sensors()
    pano, sensors = next(stream)
    stream.close()
    assert pano.image.shape == (32, 64, 3) and source.stitcher is not None
    assert "factory" in source.stitcher.rig.model
    assert sensors.sequence_id == pano.sequence_id and len(sensors.images) == 6
    assert sensors.head.source is HeadSource.FACTORY and fake.g("fake_destroyed").value == 1


def test_color_sep_jpeg_buffers_decode_like_pgr_frames(fake, tmp_path):
    rng = np.random.default_rng(0)
    image = np.clip(rng.normal(128, 20, (ROWS, COLS, 3)), 0, 255).astype(np.uint8)
    write_pgr(tmp_path / "one.pgr", [PgrFrameData(5, 0, 1, [bayer_planes(image)] * 6)])
    stream = PgrStream(tmp_path / "one.pgr")
    entry = stream.index[0]
    (tmp_path / "block.bin").write_bytes(stream._buf[entry.offset : entry.offset + entry.size])
    assert fake.handle.fake_load_block(str(tmp_path / "block.bin").encode()) == 0
    with SdkCamera(fake.library, data_format=DataFormat.COLOR_SEP_JPEG8) as camera:
        grabbed = camera.grab()
        decoded = decode_grab(grabbed, fake.library.layout, BayerPattern.RGGB)
    for got, want in zip(decoded, stream.camera_images(0), strict=True):
        np.testing.assert_array_equal(got, want)  # same bytes through ctypes as read from the file
    source = SdkFrameSource(SdkCamera(fake.library, data_format=DataFormat.COLOR_SEP_JPEG8),
                            Stitcher(tiny_rig(), PanoramaSpec(64, 32, math.inf)), time_field=DeviceTimeField.EMBEDDED)
    frames = source.frames()
    first = next(frames)
    frames.close()  # stopping the iteration stops and destroys the camera
    assert first.device_time_s == pytest.approx(1700000000.25)
    assert first.time_base.value == "gps"
    assert fake.g("fake_stopped").value == 2 and fake.g("fake_destroyed").value == 2


@pytest.mark.parametrize("pattern", [BayerPattern.BGGR, BayerPattern.RGGB])
def test_a_grabbed_jpeg_frame_in_the_documented_channel_order_keeps_blue_blue(fake, tmp_path, pattern):
    # The four channel JPEGs built by hand in the order public Ladybug code reads them; the SDK hands the block over.
    write_pgr(tmp_path / "one.pgr", [PgrFrameData(5, 0, 1, [documented_channel_jpegs(pattern.value, ROWS, COLS)] * 6)])
    entry = PgrStream(tmp_path / "one.pgr").index[0]
    (tmp_path / "block.bin").write_bytes((tmp_path / "one.pgr").read_bytes()[entry.offset : entry.end])
    assert fake.handle.fake_load_block(str(tmp_path / "block.bin").encode()) == 0
    fake.set(stippled=fake.library.layout.stippled[pattern.value])
    with SdkCamera(fake.library, data_format=DataFormat.COLOR_SEP_JPEG8) as camera:
        grabbed = camera.grab()
        images = decode_grab(grabbed, fake.library.layout, frame_pattern(grabbed, fake.library, camera.tile_pattern))
    assert all(np.all(im[..., 0] == BLUE) and np.all(im[..., 2] == RED) for im in images)


def test_the_head_of_a_pgr_streams_embedded_configuration(fake, tmp_path):
    image = np.full((ROWS, COLS, 3), 128, np.uint8)
    frame = PgrFrameData(5, 0, 1, [bayer_planes(image)] * 6)
    write_pgr(tmp_path / "s.pgr", [frame], calibration=b"FAKECAL -0.1 0.02 12.0",
              options=PgrWriteOptions(serial=17099999))
    head = head_from_pgr(fake.library, PgrStream(tmp_path / "s.pgr"), size_px=(COLS, ROWS), step_px=2)
    assert (ctypes.c_char * 256).in_dll(fake.handle, "fake_config_path").value.endswith(b"ladybug17099999.cal")
    assert head.serial == 17099999 and "embedded in the stream" in head.description
    np.testing.assert_allclose(head.sensors[0].lens.D, [-0.1, 0.02, 0, 0, 0], atol=1e-6)
    assert head.sensors[0].lens.K[0, 0] == pytest.approx(12.0)
    write_pgr(tmp_path / "bad.pgr", [frame], calibration=b"not a configuration")
    with pytest.raises(HeadCalibrationError, match="ladybugLoadConfig cannot load .*ladybug17092345.cal"):
        head_from_pgr(fake.library, PgrStream(tmp_path / "bad.pgr"), size_px=(COLS, ROWS), step_px=2)
    write_pgr(tmp_path / "none.pgr", [frame])
    with pytest.raises(HeadCalibrationError, match="holds no configuration"):
        head_from_pgr(fake.library, PgrStream(tmp_path / "none.pgr"))


def test_a_live_frame_that_lost_a_camera_still_makes_a_panorama_but_no_head_frame(fake, tmp_path):
    image = np.full((ROWS, COLS, 3), 128, np.uint8)
    write_pgr(tmp_path / "one.pgr", [PgrFrameData(5, 0, 1, [bayer_planes(image)] * 6)])
    stream = PgrStream(tmp_path / "one.pgr")
    entry = stream.index[0]
    block = bytearray(stream._buf[entry.offset : entry.offset + entry.size])
    at = int.from_bytes(block[0x340 + 4 * 32 + 8 : 0x340 + 4 * 32 + 12], "big")  # camera 4, channel 1
    block[at : at + 2] = b"\0\0"
    (tmp_path / "block.bin").write_bytes(bytes(block))
    assert fake.handle.fake_load_block(str(tmp_path / "block.bin").encode()) == 0
    source = SdkFrameSource(SdkCamera(fake.library, data_format=DataFormat.COLOR_SEP_JPEG8),
                            Stitcher(tiny_rig(), PanoramaSpec(64, 32, math.inf)), max_consecutive_failures=3)
    frames = source.frames()
    panoramas = [next(frames) for _ in range(3)]
    frames.close()
    assert len(panoramas) == 3 and (source.skipped.count, source.skipped.partial, source.skipped.channels) == (0, 3, 3)
    assert "kept without a camera: camera 4 channel 1: no JPEG start marker" in source.skipped.reasons[0]
    heads = SdkFrameSource(SdkCamera(fake.library, data_format=DataFormat.COLOR_SEP_JPEG8),
                           Stitcher(tiny_rig(), PanoramaSpec(64, 32, math.inf)), max_consecutive_failures=3)
    with pytest.raises(CorruptFrameError, match="5 of 6 cameras decode \\(6 needed\\): camera 4 channel 1"):
        next(heads.frames_with_sensors())  # a head frame needs all six: three in a row end the stream
    assert heads.skipped.count == 3
