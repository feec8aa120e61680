"""Replay: .pgr streams written by our own writer, replay directories (panoramas, or six-image frames with their
head, as capture takes them for the head dataset), and the camera->host clock."""

from __future__ import annotations

import contextlib
import math

import cv2
import numpy as np
import pytest
from ladybug5_helpers import pixel_rays_head, scaled_rig, smooth_field

from drivers.ladybug5.clock import ClockSync, unwrap_times
from drivers.ladybug5.errors import HeadCalibrationError, Ladybug5Error, StreamFormatError
from drivers.ladybug5.formats import BayerPattern
from drivers.ladybug5.frames import TimeBase
from drivers.ladybug5.head import HeadCalibration, HeadSource
from drivers.ladybug5.head_file import save_head
from drivers.ladybug5.pgr import (
    DEFAULT_LAYOUT,
    PgrFrameData,
    PgrStream,
    assemble_mosaic,
    bayer_planes,
    write_pgr,
)
from drivers.ladybug5.raw import demosaic
from drivers.ladybug5.replay import DirectoryFrameSource, PgrFrameSource
from drivers.ladybug5.rig import default_ladybug5_rig
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher, panorama_rays
from drivers.sim.motion import MotionRigSpec
from rigd.capture.config import RigSettings, SdkSettings
from rigd.capture.pair_files import rig_camera
from rigd.capture.sources import open_sources
from rigd.capture.specs import CameraKind, CameraSpec, LidarKind, LidarSpec
from rigd.dataset.records import HeadConfig

RIG = scaled_rig(default_ladybug5_rig(), 1 / 16)  # 153 x 128 px cameras
PANO = (128, 64)


def camera_images(brightness: float = 1.0) -> list[np.ndarray]:
    """Six BGR images of a direction-only field (blue, green, red channels scaled differently)."""
    out = []
    for cam in RIG.cameras:
        grey = smooth_field(pixel_rays_head(cam)).reshape(cam.height, cam.width) * brightness
        out.append(np.clip(np.stack([grey * 0.5, grey, grey * 0.8], axis=-1), 0, 255).astype(np.uint8))
    return out


def even(images):
    """Bayer mosaics need even sizes: crop one column off the 153 px wide test images."""
    return [im[: im.shape[0] // 2 * 2, : im.shape[1] // 2 * 2] for im in images]


def frame_data(seq: int, seconds: int, micro: int, images) -> PgrFrameData:
    jpegs = [bayer_planes(im, DEFAULT_LAYOUT) for im in even(images)]
    return PgrFrameData(seconds, micro, seq, jpegs, gain_raw=(seq,) * 6, shutter_raw=tuple(range(6)))


@pytest.fixture(scope="module")
def images():
    return camera_images()


@pytest.fixture(scope="module")
def even_rig():
    cams = [
        c.__class__(c.name, c.width - 1, c.height, c.K, c.D, c.R_head_camera, c.t_head_camera_m) for c in RIG.cameras
    ]
    return RIG.__class__(RIG.model, tuple(cams))


def write_stream(path, images, times=((100, 250_000), (100, 350_000), (101, 50_000))):
    frames = [frame_data(7 + i, s, us, images) for i, (s, us) in enumerate(times)]
    write_pgr(path, frames, calibration=b"calibration bytes")
    return frames


def test_pgr_index_times_and_header(tmp_path, images):
    write_stream(tmp_path / "s.pgr", images)
    stream = PgrStream(tmp_path / "s.pgr")
    assert stream.header.frame_count == 3
    assert stream.header.calibration == b"calibration bytes"
    assert [e.sequence_id for e in stream.index] == [7, 8, 9]
    np.testing.assert_allclose([e.device_time_s for e in stream.index], [100.25, 100.35, 101.05], atol=1e-9)
    assert stream.index[2].exposure.gain_raw == (9,) * 6
    assert stream.index[0].exposure.shutter_raw == (0, 1, 2, 3, 4, 5)
    assert stream.damaged == []


def test_pgr_jpeg_extraction_reassembles_the_camera_images(tmp_path, images):
    write_stream(tmp_path / "s.pgr", images)
    decoded = PgrStream(tmp_path / "s.pgr").camera_images(1)
    for got, want in zip(decoded, even(images), strict=True):
        assert got.shape == want.shape
        # JPEG + demosaicing of a smooth image: a few grey levels off, colours in the right channels.
        assert np.abs(got.astype(float) - want).mean() < 3.0


@pytest.mark.parametrize("pattern", list(BayerPattern))
def test_bayer_reassembly_puts_colours_in_the_right_channels(pattern):
    red = np.zeros((32, 32, 3), np.uint8)
    red[..., 2] = 255
    back = demosaic(assemble_mosaic(bayer_planes(red, quality=100, pattern=pattern), DEFAULT_LAYOUT, "test"), pattern)
    centre = back[4:-4, 4:-4].astype(int)
    assert centre[..., 2].min() > 240 and centre[..., :2].max() < 15


def test_pgr_replay_keeps_a_frame_that_lost_one_camera_and_counts_it(tmp_path, images, even_rig):
    write_stream(tmp_path / "s.pgr", images)
    stream = PgrStream(tmp_path / "s.pgr")
    entry = stream.index[1]
    raw = bytearray((tmp_path / "s.pgr").read_bytes())
    for camera in (3, 4):  # frame 1 loses camera 3's channel 0; frame 2 cameras 3 and 4
        if camera == 4:
            entry = stream.index[2]
        table = entry.offset + 0x340 + camera * 32
        jpeg_at = int.from_bytes(raw[table : table + 4], "big")
        raw[entry.offset + jpeg_at : entry.offset + jpeg_at + 2] = b"\x00\x00"  # destroy the JPEG's SOI
    raw[stream.index[2].offset + 0x340 + 3 * 32 + 4 : stream.index[2].offset + 0x340 + 3 * 32 + 8] = bytes(4)
    (tmp_path / "bad.pgr").write_bytes(bytes(raw))
    source = PgrFrameSource(tmp_path / "bad.pgr", Stitcher(even_rig, PanoramaSpec(*PANO)))
    frames = list(source.frames())
    assert [f.sequence_id for f in frames] == [7, 8]
    assert (source.skipped.count, source.skipped.partial, source.skipped.channels) == (1, 1, 1)
    assert "frame 1: kept without a camera: camera 3 channel 0: no JPEG start marker" in source.skipped.reasons[0]
    assert "frame 2" in source.skipped.reasons[1] and "4 of 6 cameras decode (5 needed)" in source.skipped.reasons[1]
    assert frames[0].host_time_s is None and frames[0].device_time_s == pytest.approx(100.25)
    assert frames[0].image.shape == (PANO[1], PANO[0], 3)


def test_pgr_truncated_tail_and_garbage_between_frames(tmp_path, images, even_rig):
    write_stream(tmp_path / "s.pgr", images)
    raw = (tmp_path / "s.pgr").read_bytes()
    index = PgrStream(tmp_path / "s.pgr").index
    cut = raw[: index[2].offset + index[2].size // 2]  # recording stopped mid-frame
    (tmp_path / "cut.pgr").write_bytes(cut)
    stream = PgrStream(tmp_path / "cut.pgr")
    assert len(stream.index) == 2 and len(stream.damaged) == 1
    spliced = raw[: index[1].offset] + b"\x5a" * 1000 + raw[index[1].offset :]
    (tmp_path / "spliced.pgr").write_bytes(spliced)
    stream = PgrStream(tmp_path / "spliced.pgr")
    assert [e.sequence_id for e in stream.index] == [7, 8, 9]
    assert len(stream.damaged) == 1 and "not a frame block" in stream.damaged[0]
    source = PgrFrameSource(tmp_path / "spliced.pgr", Stitcher(even_rig, PanoramaSpec(*PANO)))
    assert len(list(source.frames())) == 3 and source.skipped.count == 1


def test_pgr_found_by_fingerprint_when_head_info_offset_is_wrong(tmp_path, images):
    write_stream(tmp_path / "s.pgr", images)
    raw = bytearray((tmp_path / "s.pgr").read_bytes())
    raw[16 + DEFAULT_LAYOUT.head_data_offset : 16 + DEFAULT_LAYOUT.head_data_offset + 4] = (12).to_bytes(4, "little")
    (tmp_path / "b.pgr").write_bytes(bytes(raw))
    assert len(PgrStream(tmp_path / "b.pgr").index) == 3


def test_not_a_pgr_is_a_clear_error(tmp_path):
    (tmp_path / "x.pgr").write_bytes(b"hello" * 1000)
    with pytest.raises(StreamFormatError, match="x.pgr.*signature"):
        PgrStream(tmp_path / "x.pgr")


def test_pgr_replay_unwraps_a_wrapping_device_clock(tmp_path, images, even_rig):
    write_stream(tmp_path / "s.pgr", images, times=((127, 900_000), (0, 100_000), (0, 300_000)))
    source = PgrFrameSource(
        tmp_path / "s.pgr", Stitcher(even_rig, PanoramaSpec(*PANO)), wrap_period_s=128.0, time_base=TimeBase.GPS
    )
    frames = list(source.frames())
    np.testing.assert_allclose([f.device_time_s for f in frames], [127.9, 128.1, 128.3], atol=1e-9)
    assert frames[0].time_base is TimeBase.GPS


def write_directory(root, images):
    lines = ["image,device_time_s,host_time_s,sequence_id,shutter_s,gain_db"]
    pano = smooth_field(panorama_rays(*PANO)).astype(np.uint8)
    cv2.imwrite(str(root / "p0.png"), cv2.merge([pano] * 3))
    lines.append("p0.png,10.5,1700000000.25,3,0.002,1.5")
    (root / "p1.png").write_bytes(b"not a png")  # corrupt frame
    lines.append("p1.png,10.6,1700000000.35,4,,")
    (root / "f2").mkdir()
    for i, im in enumerate(images):
        cv2.imwrite(str(root / "f2" / f"cam{i}.png"), im)
    lines.append("f2,10.7,,,,")
    (root / "timestamps.csv").write_text("\n".join(lines) + "\n")


def test_directory_replay_times_skip_and_stitch(tmp_path, images):
    write_directory(tmp_path, images)
    stitcher = Stitcher(RIG, PanoramaSpec(*PANO, radius_m=math.inf))
    source = DirectoryFrameSource(tmp_path, stitcher)
    frames = list(source.frames())
    assert [(f.device_time_s, f.host_time_s, f.sequence_id) for f in frames] == [
        (10.5, 1700000000.25, 3),
        (10.7, None, 2),  # no sequence id: the row number
    ]
    assert frames[0].exposure.shutter_s == 0.002 and frames[0].exposure.gain_db == 1.5
    assert source.skipped.count == 1 and "p1.png" in source.skipped.reasons[0]
    # The six-image frame is stitched: the green channel reproduces the field seen from the head centre.
    expected = smooth_field(panorama_rays(*PANO))
    err = np.abs(frames[1].image[..., 1].astype(float) - expected)[stitcher.coverage]
    assert err.mean() < 1.0


def test_directory_replay_errors_name_the_file(tmp_path, images):
    (tmp_path / "timestamps.csv").write_text("image,host_time_s\nx.png,1\n")
    with pytest.raises(StreamFormatError, match=r"timestamps.csv.*device_time_s"):
        DirectoryFrameSource(tmp_path)
    (tmp_path / "timestamps.csv").write_text("image,device_time_s\nx.png,abc\n")
    with pytest.raises(StreamFormatError, match="line 2"):
        DirectoryFrameSource(tmp_path)
    write_directory(tmp_path, images)
    with pytest.raises(StreamFormatError, match="rig camera file"):
        list(DirectoryFrameSource(tmp_path).frames())


def rolled(images, k):
    """Frame k's six images: the test images rolled k columns (each frame its own images)."""
    return [np.roll(im, k, axis=1) for im in images]


def write_sensor_frames(root, images, host_times=(1700000000.25, 1700000000.45)):
    """A replay directory of six-image frames at ``host_times`` (device time 10 s earlier), a panorama frame, and a
    frame without its cam3 image (corrupt)."""
    lines = ["image,device_time_s,host_time_s,sequence_id,shutter_s,gain_db"]
    for k, host_s in enumerate(host_times):
        (root / f"f{k}").mkdir()
        for i, im in enumerate(rolled(images, k)):
            cv2.imwrite(str(root / f"f{k}" / f"cam{i}.png"), im)
        lines.append(f"f{k},{host_s - 10.0},{host_s},{5 + k},0.002,1.5")
    cv2.imwrite(str(root / "p.png"), np.zeros((PANO[1], PANO[0], 3), np.uint8))
    lines.append(f"p.png,{host_times[-1] - 9.8},{host_times[-1] + 0.2},9,,")
    (root / "broken").mkdir()
    for i, im in enumerate(images[:3]):
        cv2.imwrite(str(root / "broken" / f"cam{i}.png"), im)
    lines.append(f"broken,{host_times[-1] - 9.6},{host_times[-1] + 0.4},10,,")
    (root / "timestamps.csv").write_text("\n".join(lines) + "\n")


def test_six_image_frames_give_each_panorama_its_sensor_images_and_head(tmp_path, images):
    head = HeadCalibration.from_rig(RIG, HeadSource.FACTORY, "camera 17092345 (test)")
    write_sensor_frames(tmp_path, images)
    source = DirectoryFrameSource(tmp_path, PanoramaSpec(*PANO, radius_m=math.inf), head=head)
    pairs = list(source.frames_with_sensors())
    assert [(p.sequence_id, s is not None) for p, s in pairs] == [(5, True), (6, True), (9, False)]
    assert source.skipped.count == 1 and "no cam3 image" in source.skipped.reasons[0]
    for k, (pano, sensors) in enumerate(pairs[:2]):
        assert sensors.head is head and sensors.exposure.gain_db == 1.5
        assert (sensors.device_time_s, sensors.host_time_s, sensors.sequence_id) == (
            pano.device_time_s, pano.host_time_s, pano.sequence_id)
        for got, want in zip(sensors.images, rolled(images, k), strict=True):  # one image per sensor, as written
            np.testing.assert_array_equal(got, want)
    # The panorama is stitched from the head's geometry: it reproduces the field seen from the head centre.
    assert source.stitcher is not None and source.stitcher.rig.cameras[3].K.tolist() == RIG.cameras[3].K.tolist()
    expected = smooth_field(panorama_rays(*PANO))
    assert np.abs(pairs[0][0].image[..., 1].astype(float) - expected)[source.stitcher.coverage].mean() < 1.0


def test_the_head_of_six_image_frames_is_checked_or_comes_from_the_stitcher(tmp_path, images):
    write_sensor_frames(tmp_path, images)
    wrong = HeadCalibration.from_rig(scaled_rig(RIG, 0.5), HeadSource.FACTORY, "another head")
    with pytest.raises(HeadCalibrationError, match=r"another head\) is for sensors \[\(76, 64\).*images are \[\(153"):
        list(DirectoryFrameSource(tmp_path, head=wrong).frames_with_sensors())
    source = DirectoryFrameSource(tmp_path, Stitcher(RIG, PanoramaSpec(*PANO)))  # a rig camera file: the head
    _, sensors = next(source.frames_with_sensors())
    assert sensors.head.source is HeadSource.FILE and sensors.head.sizes == tuple((c.width, c.height)
                                                                                  for c in RIG.cameras)


def test_capture_takes_a_replays_six_image_frames_as_the_head_dataset(tmp_path, images):
    head = HeadCalibration.from_rig(RIG, HeadSource.FACTORY, "camera 17092345 (test)")
    save_head(head, tmp_path / "head.yaml")  # as `rigd camera export-head` writes it
    (tmp_path / "replay").mkdir()
    write_sensor_frames(tmp_path / "replay", images)
    settings = RigSettings(width=PANO[0], height=PANO[1], sdk=SdkSettings(rig_file=tmp_path / "head.yaml"))
    with contextlib.ExitStack() as stack:
        sources = open_sources(stack, LidarSpec(LidarKind.UDP, "127.0.0.1", 0, 0),
                               CameraSpec(CameraKind.REPLAY, tmp_path / "replay"), settings, MotionRigSpec(), 0)
        frames = sources.camera.poll(1700000000.5)
    assert [f.panorama.sequence_id for f in frames] == [5, 6] and frames[0].panorama.image.shape == (64, 128, 3)
    camera = rig_camera(frames[0])  # the dataset's rig.yaml: the head, its sensors the images' sizes
    assert isinstance(camera, HeadConfig) and [s.name for s in camera.sensors] == [c.name for c in RIG.cameras]
    assert all(np.array_equal(a, b) for a, b in zip(frames[1].sensors.images, rolled(images, 1), strict=True))


def test_clock_offset_is_the_least_delayed_sample():
    rng = np.random.default_rng(5)
    device = np.arange(500) * 0.1
    offset = 1_700_000_000.0 - 3.0
    latency = rng.exponential(0.004, size=500) + 0.0005
    clock = ClockSync(window=300)
    for d, lat in zip(device, latency, strict=True):
        clock.add(d, d + offset + lat)
    report = clock.report()
    assert report.offset_s - offset == pytest.approx(latency[-300:].min(), abs=1e-6)
    assert 0.0 < report.spread_s < 0.01 and report.samples == 500
    assert clock.to_host(42.0) == pytest.approx(42.0 + offset, abs=0.002)


def test_clock_unwraps_cycle_time_like_the_batch_unwrap():
    true = np.arange(0, 400, 0.7)
    raw = np.mod(true, 128.0)
    clock = ClockSync(wrap_period_s=128.0)
    streamed = [clock.add(r, 0.0) for r in raw]
    np.testing.assert_allclose(streamed, true, atol=1e-9)
    np.testing.assert_allclose(unwrap_times(raw, 128.0), true, atol=1e-9)


def test_clock_without_samples_is_an_error():
    with pytest.raises(Ladybug5Error, match="no .* samples"):
        ClockSync().to_host(1.0)
