"""Live frames from the SDK: the six raw sensor images with the head calibration, or panoramas (rigd's stitcher or
the SDK's renderer, :mod:`drivers.ladybug5.sdk_render`).

A frame that fails -- a grab error or timeout, a corrupt buffer, a stitch or render that fails -- is skipped and
counted (``skipped``), never the end of the stream; ``max_consecutive_failures`` failures in a row end it with
the last error. A failed exposure read (``ladybugGetAbsProperty``) gives the frame an unknown exposure and is
counted in ``exposure_errors``. A data format rigd does not decode ends the stream at once (every frame would
fail the same way). Needs FLIR's SDK (through :class:`drivers.ladybug5.sdk.SdkCamera`).
"""

from __future__ import annotations

from collections.abc import Iterator
from enum import Enum
from typing import Any

import numpy as np

from drivers.ladybug5.clock import ClockSync
from drivers.ladybug5.errors import CorruptFrameError, HeadCalibrationError, Ladybug5Error, RendererError, SdkError
from drivers.ladybug5.formats import BayerPattern
from drivers.ladybug5.frames import Exposure, PanoramaFrame, SensorFrame, SkipCounter, TimeBase
from drivers.ladybug5.head import HeadCalibration, HeadSource
from drivers.ladybug5.pgr import DEFAULT_LAYOUT, CameraSet, PgrLayout
from drivers.ladybug5.raw import NUM_SENSORS
from drivers.ladybug5.replay import PARTIAL_FRAME_CAMERAS
from drivers.ladybug5.sdk import CYCLE_PERIOD_S, DeviceTimeField, SdkCamera, decode_grab_cameras, frame_pattern
from drivers.ladybug5.sdk_head import DEFAULT_MAP_STEP_PX
from drivers.ladybug5.sdk_library import GrabbedImage
from drivers.ladybug5.sdk_render import PanoramaBackend, PanoramaRenderer, StitcherBackend, panorama_renderer
from drivers.ladybug5.stitch import PanoramaSpec, Stitcher


class HeadPolicy(Enum):
    """Which head calibration a live source uses when none is given."""

    FACTORY = "factory"  # read from the SDK (ladybugLoadConfig's calibration); an error if it cannot be read
    NOMINAL = "nominal"  # rigd's nominal head at the camera's sensor size: NOT a calibration (say so to users)


class SdkSensorSource:
    """Six raw sensor images per frame (debayered, border-cropped) with the head calibration.

    ``head``: a :class:`HeadCalibration` (e.g. from ``rigd camera export-head``), or a :class:`HeadPolicy`: the
    factory head is read through the SDK once the first frame gives the sensor size. ``bayer_pattern`` None
    takes the SDK's.
    """

    def __init__(self, camera: SdkCamera, head: HeadCalibration | HeadPolicy = HeadPolicy.FACTORY,
                 bayer_pattern: BayerPattern | None = None, pgr_layout: PgrLayout = DEFAULT_LAYOUT,
                 time_field: DeviceTimeField = DeviceTimeField.CYCLE, max_consecutive_failures: int = 30,
                 map_step_px: int = DEFAULT_MAP_STEP_PX) -> None:
        self.camera = camera
        self.head_choice = head
        self.head: HeadCalibration | None = head if isinstance(head, HeadCalibration) else None
        self.bayer_pattern = bayer_pattern
        self.pgr_layout = pgr_layout
        self.time_field = time_field
        self.max_failures = max_consecutive_failures
        self.map_step_px = map_step_px
        cycle = time_field is DeviceTimeField.CYCLE
        self.clock = ClockSync(
            wrap_period_s=CYCLE_PERIOD_S if cycle else None, time_base=TimeBase.CAMERA if cycle else TimeBase.GPS
        )
        self.skipped = SkipCounter()
        self.exposure_errors = SkipCounter()
        self._failures = 0

    def failed(self, error: Ladybug5Error) -> None:
        """Count a frame that failed; the ``max_consecutive_failures``-th in a row ends the stream with it."""
        self._failures += 1
        self.skipped.record(error)
        if self._failures >= self.max_failures:
            raise error

    def _grab(self, min_cameras: int) -> tuple[GrabbedImage, CameraSet] | None:
        """A grabbed, decoded frame (at least ``min_cameras`` cameras), or None after a failure that was counted."""
        try:
            image = self.camera.grab()
            pattern = frame_pattern(image, self.camera.lib, self.camera.tile_pattern, self.bayer_pattern)
            return image, decode_grab_cameras(image, self.camera.lib.layout, pattern, self.pgr_layout, min_cameras)
        except (CorruptFrameError, SdkError) as exc:  # a timeout is an SdkError too
            self.failed(exc)
            return None

    def _head_for(self, images: list[Any]) -> HeadCalibration:
        size = (images[0].shape[1], images[0].shape[0])
        if self.head is None:
            if self.head_choice is HeadPolicy.NOMINAL:
                self.head = HeadCalibration.nominal(size)
            else:
                self.head = self.camera.read_head(size, self.map_step_px)
        sizes = {(im.shape[1], im.shape[0]) for im in images}
        if sizes != set(self.head.sizes):
            raise HeadCalibrationError(f"{self.camera.describe}: the head calibration ({self.head.description}) is "
                                       f"for sensors {sorted(set(self.head.sizes))}, the camera sends {sorted(sizes)}")
        return self.head

    def _exposure(self) -> Exposure:
        try:
            return self.camera.exposure()
        except SdkError as exc:  # the frame is still good; its exposure is unknown
            self.exposure_errors.record(exc)
            return Exposure()

    def frames(self, min_cameras: int = NUM_SENSORS) -> Iterator[SensorFrame]:
        """Frames with all six cameras; with ``min_cameras`` below six (panoramas only: rigd's head datasets need
        every sensor) also frames that lost a camera, its image zero and its number in ``missing_cameras``."""
        with self.camera:
            while True:
                grabbed = self._grab(min_cameras)
                if grabbed is None:
                    continue
                image, cameras = grabbed
                head = self._head_for([im for im in cameras.arrays if im is not None])
                if cameras.faults:
                    self.skipped.record_partial(f"grabbed frame {image.sequence_id}", cameras.faults)
                images = tuple(np.zeros((h, w, 3), np.uint8) if im is None else im
                               for im, (w, h) in zip(cameras.arrays, head.sizes, strict=True))
                raw = image.cycle_time_s if self.time_field is DeviceTimeField.CYCLE else image.embedded_time_s
                device_s = self.clock.add(raw, image.host_receive_s)
                skipped = self.skipped.count
                yield SensorFrame(images, head, device_s, self.clock.to_host(device_s), image.sequence_id,
                                  self._exposure(), self.clock.time_base, cameras.missing)
                if self.skipped.count == skipped:  # the consumer used it (a failed stitch is counted here too)
                    self._failures = 0

    def close(self) -> None:
        self.camera.close()


class SdkFrameSource:
    """Live panoramas: :class:`SdkSensorSource` frames, each made into a panorama by the ``panorama`` backend.

    ``stitcher``: a ready :class:`Stitcher` (its rig is the head used), or a :class:`PanoramaSpec`: then the
    head comes from ``head`` (default: the factory head read through the SDK) and the stitcher is built from it
    at the first frame. ``panorama`` :attr:`PanoramaBackend.SDK_RENDERER` renders with FLIR's renderer instead, at
    the spec's size (:mod:`drivers.ladybug5.sdk_render`). ``skipped`` counts failed grabs and failed panoramas
    alike; a renderer that cannot be set up (no OpenGL) ends the stream.
    """

    def __init__(self, camera: SdkCamera, stitcher: Stitcher | PanoramaSpec,
                 bayer_pattern: BayerPattern | None = None, pgr_layout: PgrLayout = DEFAULT_LAYOUT,
                 time_field: DeviceTimeField = DeviceTimeField.CYCLE, max_consecutive_failures: int = 30,
                 head: HeadCalibration | HeadPolicy = HeadPolicy.FACTORY, *,
                 panorama: PanoramaBackend = PanoramaBackend.RIGD_STITCHER) -> None:
        ready = stitcher if isinstance(stitcher, Stitcher) else None
        self.spec: PanoramaSpec = stitcher.spec if isinstance(stitcher, Stitcher) else stitcher
        if ready is not None:
            head = HeadCalibration.from_rig(ready.rig, HeadSource.FILE, ready.rig.model)
        self.backend = panorama
        self.renderer: PanoramaRenderer = panorama_renderer(panorama, camera, spec=self.spec, stitcher=ready)
        self.sensors = SdkSensorSource(camera, head, bayer_pattern, pgr_layout, time_field, max_consecutive_failures)
        self.camera = camera
        self.clock = self.sensors.clock
        self.skipped = self.sensors.skipped
        self.exposure_errors = self.sensors.exposure_errors

    @property
    def stitcher(self) -> Stitcher | None:
        """rigd's stitcher (None before the first frame, and with the SDK's renderer)."""
        return self.renderer.stitcher if isinstance(self.renderer, StitcherBackend) else None

    def _panorama(self, frame: SensorFrame) -> PanoramaFrame | None:
        try:
            pano = self.renderer.panorama(frame)
        except RendererError:
            raise  # no frame can be rendered
        except Ladybug5Error as exc:  # one frame that does not stitch or render is one frame lost
            self.sensors.failed(exc)
            return None
        return PanoramaFrame(pano, frame.device_time_s, frame.host_time_s, frame.sequence_id, frame.exposure,
                             frame.time_base)

    def frames_with_sensors(self) -> Iterator[tuple[PanoramaFrame, SensorFrame]]:
        """Each panorama with the sensor frame it was stitched from: for a capture whose stillness check looks at
        panoramas and whose head dataset takes the six sensor images (and their head) of the same frame."""
        for frame in self.sensors.frames():
            pano = self._panorama(frame)
            if pano is not None:
                yield pano, frame

    def frames(self) -> Iterator[PanoramaFrame]:
        """Panoramas; with rigd's stitcher also of frames that lost one camera (its view left to its neighbours)."""
        stitched = self.backend is PanoramaBackend.RIGD_STITCHER
        for frame in self.sensors.frames(PARTIAL_FRAME_CAMERAS if stitched else NUM_SENSORS):
            pano = self._panorama(frame)
            if pano is not None:
                yield pano

    def close(self) -> None:
        self.camera.close()
