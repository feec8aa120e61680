"""A captured pair's camera side: the panorama, or the head's sensor images with the panorama beside them; and
whether a resumed capture's frames fit the dataset's rig.yaml."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from drivers.ladybug5 import Exposure, PanoramaFrame, SensorFrame
from drivers.ladybug5.rig import scaled_ladybug5_rig
from drivers.ladybug5.sim import simulated_head
from rigd.capture.pair_files import PANORAMA_FILE, camera_difference, pair_bytes, pair_images, rig_camera
from rigd.capture.sources import CameraFrame
from rigd.dataset import RigConfig
from rigd.dataset.records import HeadConfig


def _frame(width: int, sensors: bool) -> CameraFrame:
    panorama = PanoramaFrame(np.zeros((32, 64, 3), np.uint8), 1.0, 2.0, 3, Exposure())
    if not sensors:
        return CameraFrame(panorama)
    head = simulated_head(scaled_ladybug5_rig(width))
    images = tuple(np.full((h, w, 3), i, np.uint8) for i, (w, h) in enumerate(head.sizes))
    return CameraFrame(panorama, SensorFrame(images, head, 1.0, 2.0, 3, Exposure()))


def test_a_head_frame_is_its_sensor_images_and_the_panorama_beside_them() -> None:
    frame = _frame(16, sensors=True)
    images, extras = pair_images(frame)
    assert isinstance(images, dict) and list(images) == [f"cam{i}" for i in range(6)]
    assert [int(im[0, 0, 0]) for im in images.values()] == list(range(6))  # each name its own sensor's image
    assert list(extras) == [PANORAMA_FILE] and extras[PANORAMA_FILE] is frame.panorama.image
    assert pair_bytes(frame) == frame.panorama.image.nbytes + sum(im.nbytes for im in images.values())
    panorama_only = _frame(16, sensors=False)
    assert pair_images(panorama_only) == (panorama_only.panorama.image, {})
    assert (rig_camera(panorama_only).width, rig_camera(panorama_only).height) == (64, 32)


def test_a_resumed_capture_must_bring_the_same_head() -> None:
    head = rig_camera(_frame(16, sensors=True))
    assert isinstance(head, HeadConfig)
    written = RigConfig.from_yaml(RigConfig(head).to_yaml(), "rig.yaml").camera  # as read back from the file
    assert camera_difference(written, head) is None
    assert "16x13" in str(camera_difference(written, rig_camera(_frame(24, sensors=True))))
    moved = replace(head, sensors=(replace(head.sensors[0], T_head_camera=head.sensors[1].T_head_camera),
                                   *head.sensors[1:]))
    assert "cam0" in str(camera_difference(written, moved))
    assert "equirectangular" in str(camera_difference(rig_camera(_frame(16, sensors=False)), head))
    assert "says 64x32" in str(camera_difference(rig_camera(_frame(16, sensors=False)),
                                                 replace(rig_camera(_frame(16, sensors=False)), width=128)))
