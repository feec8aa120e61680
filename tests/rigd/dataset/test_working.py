"""The working resolution: halved images keep the camera model exact (pixel centres at integer coordinates)."""

from pathlib import Path

import numpy as np
import pytest

from rigd.dataset import CameraConfig, CameraKind, RigConfig, open_dataset, write_pair, write_rig
from rigd.dataset.pcd import Cloud
from rigd.dataset.working import halve_camera, halve_image, halvings, working_camera
from rigd.errors import DatasetError

PANORAMA = CameraConfig(CameraKind.EQUIRECTANGULAR, 64, 32)
PINHOLE = CameraConfig(CameraKind.PINHOLE, 61, 41, np.array([[50.0, 0.5, 30.2], [0.0, 52.0, 20.7], [0.0, 0.0, 1.0]]),
                       np.array([-0.1, 0.02, 0.001, -0.002, 0.0]))


def _rays(n: int, seed: int) -> np.ndarray:
    """(n,3) float64 points in front of either camera model's optical axis."""
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform(-0.5, 0.5, (n, 2)), np.ones(n)] * rng.uniform(2, 20, (n, 1))


@pytest.mark.parametrize("camera", [PANORAMA, PINHOLE], ids=["equirectangular", "pinhole"])
def test_halved_camera_projects_to_half_the_pixel_coordinates(camera):
    points_cam = _rays(200, 0)
    uv_full, ok_full = camera.model().project(points_cam)
    uv_half, ok_half = halve_camera(camera).model().project(points_cam)
    assert ok_full.sum() > 50
    both = ok_full & ok_half
    np.testing.assert_allclose(uv_half[both], uv_full[both] / 2.0, atol=1e-9)


@pytest.mark.parametrize("camera", [PANORAMA, PINHOLE], ids=["equirectangular", "pinhole"])
def test_a_bright_source_pixel_lands_on_the_working_pixel_of_half_its_coordinates(camera):
    image = np.zeros((camera.height, camera.width), np.uint8)
    image[12, 22] = 255
    half = halve_image(image, camera.kind is CameraKind.EQUIRECTANGULAR)
    assert half.shape == ((camera.height + 1) // 2, (camera.width + 1) // 2)
    assert np.unravel_index(np.argmax(half), half.shape) == (6, 11)


def test_a_panorama_is_blurred_across_its_seam_and_a_pinhole_image_is_not():
    image = np.zeros((32, 64), np.uint8)
    image[:, 0] = 255  # the column at azimuth +180 deg, next to the last column
    assert halve_image(image, wrap_u=True)[:, -1].min() > 0
    assert halve_image(image, wrap_u=False)[:, -1].max() == 0


@pytest.mark.parametrize(("camera", "max_width", "expected"), [
    (CameraConfig(CameraKind.EQUIRECTANGULAR, 8192, 4096), 2048, 2),
    (CameraConfig(CameraKind.EQUIRECTANGULAR, 8000, 4000), 2048, 2),  # 2000 x 1000
    (CameraConfig(CameraKind.EQUIRECTANGULAR, 2048, 1024), 2048, 0),
    (CameraConfig(CameraKind.EQUIRECTANGULAR, 8192, 4096), None, 0),
    (CameraConfig(CameraKind.EQUIRECTANGULAR, 4002, 2001), 2048, 0),  # odd height: not halved exactly
    (PINHOLE, 20, 2),  # 61 -> 31 -> 16
])
def test_halvings(camera, max_width, expected):
    assert halvings(camera, max_width) == expected
    if max_width and expected:
        assert working_camera(camera, expected).width <= max_width


def test_opened_at_a_working_width_the_dataset_halves_its_images_and_its_camera(tmp_path: Path):
    write_rig(tmp_path, RigConfig(PINHOLE))
    image = np.random.default_rng(1).integers(0, 255, (41, 61, 3), dtype=np.uint8)
    write_pair(tmp_path, 0, image, Cloud(_rays(50, 2)), {})
    dataset = open_dataset(tmp_path, max_width=40)
    assert dataset.halvings == 1 and dataset.source_camera.width == PINHOLE.width
    assert (dataset.rig.camera.width, dataset.rig.camera.height) == (31, 21)
    np.testing.assert_allclose(dataset.rig.camera.K[:2], PINHOLE.K[:2] / 2)
    assert dataset.load_pair(0).image.shape == (21, 31, 3)
    assert open_dataset(tmp_path).load_pair(0).image.shape == image.shape


def test_a_wrong_size_image_is_named_with_the_size_rig_yaml_gives(tmp_path: Path):
    write_rig(tmp_path, RigConfig(PINHOLE))
    write_pair(tmp_path, 0, np.zeros((40, 61), np.uint8), Cloud(_rays(50, 2)), {})
    with pytest.raises(DatasetError, match="image is 61x40, rig.yaml says 61x41"):
        open_dataset(tmp_path, max_width=40).load_pair(0)
