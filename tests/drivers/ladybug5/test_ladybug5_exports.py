"""Replay of what people have: FLIR-exported camera images (their names, upright or in sensor orientation, raw or
rectified, a flat folder), and 1-channel Bayer mosaics; each detected and said."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from ladybug5_helpers import pixel_rays_head, render_scene, smooth_field

from drivers.ladybug5.exports import camera_number, rectified_head
from drivers.ladybug5.formats import BayerPattern
from drivers.ladybug5.head import HeadCalibration, HeadSource
from drivers.ladybug5.replay import DirectoryFrameSource
from drivers.ladybug5.rig import RigCamera, scaled_ladybug5_rig
from drivers.ladybug5.stitch import PanoramaSpec, panorama_rays

RIG = scaled_ladybug5_rig(48)  # 48 x 40 px sensors
PANO = PanoramaSpec(96, 48, math.inf)


def field_image(camera: RigCamera) -> np.ndarray:
    """(H, W, 3) uint8 BGR of a field that depends on direction only (channels scaled differently)."""
    grey = smooth_field(pixel_rays_head(camera)).reshape(camera.height, camera.width)
    return np.clip(np.stack([grey * 0.5, grey, grey * 0.8], axis=-1), 0, 255).astype(np.uint8)


def factory_head() -> HeadCalibration:
    head = HeadCalibration.from_rig(RIG, HeadSource.FACTORY, "camera 17092345 (test)")
    # the SDK's rectified pinhole: a third of the raw focal length, centres off the middle by camera
    sensors = tuple(replace(s, focal_px=s.lens.K[0, 0] / 3, centre_px=(22.0 + c, 20.5 - c))
                    for c, s in enumerate(head.sensors))
    return replace(head, sensors=sensors)


def timestamps(root, *images: str) -> None:
    rows = [f"{name},{10 + i}.0,{1700000000 + i}.0,{i}" for i, name in enumerate(images)]
    (root / "timestamps.csv").write_text("image,device_time_s,host_time_s,sequence_id\n" + "\n".join(rows) + "\n")


def test_flir_names_are_read_for_their_camera_number():
    names = ["ladybug_17092345_000005_Cam3.jpg", "pano_Camera_0.png", "frame12-cam05.tif", "CAMERA-2.PNG",
             "cam4.png", "Cam12.jpg", "scam1.png", "ladybug_Rectified_1024x768_00000020_Cam1.jpg"]
    assert [camera_number(n) for n in names] == [3, 0, 5, 2, 4, None, None, 1]


def test_upright_flir_exports_in_a_flat_folder_are_turned_back_and_said(tmp_path, caplog):
    sensor_images = [field_image(c) for c in RIG.cameras]
    for c, image in enumerate(sensor_images):  # upright: turned 90 degrees clockwise, FLIR-like names, one folder
        cv2.imwrite(str(tmp_path / f"ladybug_17092345_000005_Cam{c}.png"), np.rot90(image, -1))
    timestamps(tmp_path, "ladybug_17092345_000005")
    source = DirectoryFrameSource(tmp_path, PANO, head=factory_head())
    pano, sensors = next(source.frames_with_sensors())
    assert sensors is not None and source.skipped.count == 0
    for got, want in zip(sensors.images, sensor_images, strict=True):
        np.testing.assert_array_equal(got, want)  # back in sensor orientation, exactly
    assert "names like ladybug_17092345_000005_Cam0.png, upright orientation" in source.layouts[0]
    assert "upright orientation" in caplog.text  # said, as it is not rigd's own layout
    expected = smooth_field(panorama_rays(PANO.width, PANO.height))
    assert source.stitcher is not None
    assert np.abs(pano.image[..., 1].astype(float) - expected)[source.stitcher.coverage].mean() < 1.0


def test_upright_means_the_heads_up_is_at_the_top():
    """The turn is the head's geometry, not a guess: in a side camera's upright image the rows' rays rise towards
    row 0 (+z up), and its columns run to the right (the ray turns clockwise seen from above)."""
    for camera in RIG.cameras[:5]:
        rays = pixel_rays_head(camera).reshape(camera.height, camera.width, 3)
        upright = np.rot90(rays, -1)
        centre_col, centre_row = upright.shape[1] // 2, upright.shape[0] // 2
        assert np.all(np.diff(upright[:, centre_col, 2]) < 0)  # z falls from the top row down
        azimuth = np.unwrap(np.arctan2(upright[centre_row, :, 1], upright[centre_row, :, 0]))
        assert np.all(np.diff(azimuth) < 0)  # left to right = clockwise from above (azimuth falls)


def test_rectified_exports_go_with_the_rectified_pinholes(tmp_path):
    head = factory_head()
    size = (36, 30)  # exported at another size than the sensors'
    rect = rectified_head(head, size)
    (tmp_path / "f").mkdir()
    for c, camera in enumerate(rect.to_rig().cameras):
        cv2.imwrite(str(tmp_path / "f" / f"ladybug_Rectified_{size[0]}x{size[1]}_00000007_Cam{c}.png"),
                    field_image(camera))
    timestamps(tmp_path, "f")
    source = DirectoryFrameSource(tmp_path, PANO, head=head)
    pano, sensors = next(source.frames_with_sensors())
    assert sensors is not None and sensors.head.source is HeadSource.FACTORY
    k = sensors.head.sensors[2].lens.K
    assert np.all(sensors.head.sensors[2].lens.D == 0)
    scale = size[0] / RIG.cameras[2].width
    assert k[0, 0] == pytest.approx(head.sensors[2].focal_px * scale)
    assert k[0, 2] == pytest.approx((head.sensors[2].centre_px[0] + 0.5) * scale - 0.5)
    assert "rectified images" in source.layouts[0]
    expected = smooth_field(panorama_rays(PANO.width, PANO.height))
    stitched = source._stitcher_for(sensors.head)
    assert np.abs(pano.image[..., 1].astype(float) - expected)[stitched.coverage].mean() < 1.0


def test_rectified_exports_without_the_heads_pinholes_are_nominal():
    head = HeadCalibration.from_rig(RIG, HeadSource.FACTORY, "lens from the 3D map")
    head = replace(head, sensors=tuple(replace(s, focal_px=float("nan")) for s in head.sensors))
    rect = rectified_head(head, (48, 40))
    assert rect.source is HeadSource.NOMINAL and "public factory calibrations" in rect.description
    assert rect.sensors[0].lens.K[0, 0] == pytest.approx(452.0 * 48 / 2448)


@pytest.mark.parametrize("pattern", list(BayerPattern))
def test_one_channel_images_are_bayer_mosaics_when_a_pattern_is_given(tmp_path, pattern):
    (tmp_path / "f").mkdir()
    colour = (40, 120, 210)  # B, G, R
    for c, camera in enumerate(RIG.cameras):  # a flat colour mosaiced by hand: each cell samples its channel
        mosaic = np.empty((camera.height, camera.width), np.uint8)
        for r in (0, 1):
            for q in (0, 1):
                mosaic[r::2, q::2] = colour["BGR".index(pattern.value[2 * r + q])]
        cv2.imwrite(str(tmp_path / "f" / f"cam{c}.png"), mosaic)
    timestamps(tmp_path, "f")
    head = HeadCalibration.from_rig(RIG, HeadSource.FILE, "test")
    _, bayer = next(DirectoryFrameSource(tmp_path, PANO, pattern, head=head).frames_with_sensors())
    _, grey = next(DirectoryFrameSource(tmp_path, PANO, head=head).frames_with_sensors())
    assert bayer is not None and grey is not None
    inner = bayer.images[3][2:-2, 2:-2].reshape(-1, 3)
    assert np.all(np.abs(inner.astype(int) - colour) <= 1)  # demosaiced: the colour back
    assert np.all(grey.images[3][..., 0] == grey.images[3][..., 2])  # no pattern: taken as grey


def test_a_frame_with_a_camera_missing_or_doubled_is_skipped_by_name(tmp_path):
    for frame in ("a", "b"):
        (tmp_path / frame).mkdir()
        for c, camera in enumerate(RIG.cameras):
            cv2.imwrite(str(tmp_path / frame / f"x_Cam{c}.png"), field_image(camera))
    (tmp_path / "a" / "x_Cam4.png").unlink()
    cv2.imwrite(str(tmp_path / "b" / "y_camera_2.png"), field_image(RIG.cameras[2]))
    timestamps(tmp_path, "a", "b")
    source = DirectoryFrameSource(tmp_path, PANO, head=HeadCalibration.from_rig(RIG, HeadSource.FILE, "t"))
    assert list(source.frames()) == [] and source.skipped.count == 2
    assert "no cam4 image" in source.skipped.reasons[0]
    assert "camera 2 in 2 files (x_Cam2.png, y_camera_2.png)" in source.skipped.reasons[1]


@pytest.mark.parametrize(("yaw", "mirrored", "upside_down"), [(0.0, False, False), (30.0, False, False),
                                                              (-144.0, True, False), (72.0, False, True)])
def test_another_panoramas_orientation_is_measured_against_a_known_scene(yaw, mirrored, upside_down):
    from drivers.ladybug5.pano_check import panorama_alignment

    reference = render_scene(720)
    other = cv2.cvtColor(render_scene(1024, yaw, mirrored, upside_down), cv2.COLOR_GRAY2BGR)  # another size
    found = panorama_alignment(other, reference)
    assert (found.mirrored, found.upside_down) == (mirrored, upside_down)
    assert found.yaw_deg == pytest.approx(yaw, abs=0.2)
    assert found.same_convention == (yaw == 0.0 and not mirrored and not upside_down)
    assert found.score > 0.5 > found.runner_up
