"""The simulated rig's Ladybug: six pinhole views rendered by drivers.sim, stitched like real frames.

Each rig camera is rendered from its own centre (``T_world_head @ T_head_camera``) with drivers.sim's
``render_rays``, one ray per pixel through the camera's exact (iteratively undistorted) pixel direction,
then stitched by :class:`Stitcher`, so the sim exercises the same stitching and parallax as the real head.
Device time starts at ``device_start_s`` and ticks ``frame_period_s``; host time is device time plus
``host_offset_s`` (a known offset, for testing clock mapping downstream). ``frames_with_sensors()`` gives each
panorama with the six sensor images it was stitched from and the head they go with (the simulated head is
exact: its own factory calibration), as the live SDK source does.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.ladybug5.frames import Exposure, PanoramaFrame, SensorFrame, SkipCounter
from drivers.ladybug5.head import HeadCalibration, HeadSource
from drivers.ladybug5.rig import RigCamera, RigCameras
from drivers.ladybug5.stitch import Stitcher
from drivers.sim import Pose, Scene, render_rays
from drivers.sim.camera import quantise

F64 = NDArray[np.float64]
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)


def pixel_rays_optical(camera: RigCamera) -> F64:
    """Unit rays (H*W, 3) in the camera's optical frame through every pixel centre, row-major.

    OpenCV's default undistortion stops after 5 iterations, too few for a wide barrel lens near the
    corners; 100 iterations converge to well under 0.01 px for the default head.
    """
    u, v = np.meshgrid(np.arange(camera.width, dtype=np.float64), np.arange(camera.height, dtype=np.float64))
    uv = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    xy = cv2.undistortPoints(uv, camera.K, camera.D, None, None, None, _UNDISTORT_CRITERIA).reshape(-1, 2)
    rays = np.column_stack([xy, np.ones(len(xy))])
    unit: F64 = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    return unit


def simulated_head(rig: RigCameras) -> HeadCalibration:
    """The head calibration of a simulated Ladybug rendered with ``rig``: exact, so it is the camera's own."""
    return HeadCalibration.from_rig(rig, HeadSource.FACTORY, f"simulated Ladybug (exact): {rig.model}")


def sensor_displays(scene: Scene, pose_world_head: Pose, cameras: Sequence[RigCamera],
                    rays: Sequence[F64]) -> list[F64]:
    """Noise-free display values (H, W) float in [0, 1] of each camera's raw image seen from
    ``pose_world_head``; ``rays``: each camera's :func:`pixel_rays_optical`."""
    rotation = np.asarray(pose_world_head.rotation, dtype=np.float64)
    displays = []
    for camera, camera_rays in zip(cameras, rays, strict=True):
        origin = pose_world_head.apply(camera.t_head_camera_m[None, :])[0]
        value = render_rays(scene, origin, rotation @ camera.R_head_camera, camera_rays)
        displays.append(value.reshape(camera.height, camera.width).astype(np.float64))
    return displays


class SimFrameSource:
    """Frames of the simulated Ladybug at ``poses_world_head`` (one frame each) in ``scene``."""

    def __init__(
        self,
        scene: Scene,
        poses_world_head: Sequence[Pose],
        stitcher: Stitcher,
        rng: np.random.Generator,
        noise_grey: float = 1.5,
        frame_period_s: float = 0.1,
        device_start_s: float = 0.0,
        host_offset_s: float = 0.0,
    ) -> None:
        self.scene = scene
        self.poses = list(poses_world_head)
        self.stitcher = stitcher
        self.rng = rng
        self.noise_grey = noise_grey
        self.frame_period_s = frame_period_s
        self.device_start_s = device_start_s
        self.host_offset_s = host_offset_s
        self.skipped = SkipCounter()  # the simulator never produces a bad frame
        self._rays = [pixel_rays_optical(c) for c in stitcher.rig.cameras]

    def camera_images(self, pose_world_head: Pose) -> list[NDArray[np.uint8]]:
        """Six BGR uint8 images (each camera's raw image) seen from ``pose_world_head``."""
        displays = sensor_displays(self.scene, pose_world_head, self.stitcher.rig.cameras, self._rays)
        return [np.asarray(cv2.cvtColor(quantise(d, self.rng, self.noise_grey), cv2.COLOR_GRAY2BGR), dtype=np.uint8)
                for d in displays]

    def frames_with_sensors(self) -> Iterator[tuple[PanoramaFrame, SensorFrame]]:
        """Each panorama with the six sensor images it was stitched from and the (exact) head."""
        head = simulated_head(self.stitcher.rig)
        for k, pose in enumerate(self.poses):
            device_s = self.device_start_s + k * self.frame_period_s
            images = self.camera_images(pose)
            host_s = device_s + self.host_offset_s
            yield (PanoramaFrame(self.stitcher.stitch(images), device_s, host_s, k, Exposure()),
                   SensorFrame(tuple(images), head, device_s, host_s, k, Exposure()))

    def frames(self) -> Iterator[PanoramaFrame]:
        for pano, _ in self.frames_with_sensors():
            yield pano

    def close(self) -> None:
        """Nothing to release."""
