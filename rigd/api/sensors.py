"""Sensor health for ``GET /status``: checked in a background thread, served from the last snapshot.

The LiDAR is probed by listening to its UDP stream for a moment (packet rate, lost packets, PPS state from
the position packets), the camera by USB enumeration (presence, negotiated speed, usbfs limit). While a
capture holds the sensors the probe stands aside and the capture's own figures are shown instead.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from drivers.errors import DriverError
from drivers.ladybug5.usb import find_cameras, health_warnings, read_usbfs_memory_mb
from drivers.vlp16 import Ports, UdpReceiver
from rigd.api.models import CameraStatus, LidarStatus
from rigd.capture.specs import CameraKind, LidarKind, LidarSpec, parse_camera, parse_lidar
from rigd.store.db import utc_now


def probe_lidar(source: LidarSpec, listen_s: float) -> LidarStatus:
    """Listen ``listen_s`` seconds to the LiDAR's UDP ports and report what arrived."""
    name = str(source)
    try:
        with UdpReceiver(host=source.host, ports=Ports(source.data_port, source.position_port)) as receiver:
            sweeps = list(receiver.sweeps(timeout_s=listen_s))
            stats = receiver.stats
    except DriverError as exc:
        return LidarStatus(source=name, state="error", checked_at=utc_now(), message=str(exc))
    if stats.data_packets == 0:
        return LidarStatus(source=name, state="silent", packet_rate_hz=0.0, checked_at=utc_now(),
                           message=f"no data packet in {listen_s:.1f} s")
    # The rate over the time the packets arrived in (host clock), not the listening window, which the
    # stream may have started or stopped inside of.
    span_s = sweeps[-1].end.host - sweeps[0].start.host if sweeps else 0.0
    rate = (stats.data_packets - 1) / span_s if span_s > 0 else None
    return LidarStatus(
        source=name, state="ok", packet_rate_hz=rate,
        packets_lost=stats.missing_packets + stats.overruns,
        pps=stats.pps.name.lower() if stats.pps is not None else None, checked_at=utc_now(),
        message=f"{stats.bad_packets} bad packets" if stats.bad_packets else "")


def probe_camera(source: str) -> CameraStatus:
    if parse_camera(source).kind is not CameraKind.SDK:
        return CameraStatus(source=source, checked_at=utc_now(), message="no USB camera is used by this source")
    try:
        cameras, unidentified = find_cameras()
    except DriverError as exc:
        return CameraStatus(source=source, checked_at=utc_now(), message=str(exc))
    warnings = health_warnings(cameras, read_usbfs_memory_mb())
    if unidentified and not cameras:
        warnings.append(f"{len(unidentified)} FLIR/Point Grey device(s) whose name cannot be read (permissions?)")
    first = cameras[0] if cameras else None
    return CameraStatus(source=source, present=first is not None, usb_speed=first.speed.label if first else None,
                        serial=first.serial if first else None, warnings=warnings, checked_at=utc_now())


class SensorMonitor:
    """Keeps the last sensor snapshot; ``capture_figures`` gives a running capture's LiDAR and camera status, or
    None."""

    def __init__(self, camera_source: str, lidar_source: str, poll_s: float,
                 capture_figures: Callable[[], tuple[LidarStatus, CameraStatus] | None], listen_s: float = 1.0
                 ) -> None:
        self.camera_source = camera_source
        self.lidar_source = lidar_source
        spec = parse_lidar(lidar_source)
        self.udp = spec if spec.kind is LidarKind.UDP else None
        self.poll_s = poll_s
        self.listen_s = listen_s
        self.capture_figures = capture_figures
        # Held while probing the LiDAR; a capture takes it before opening the sensors.
        self.lidar_lock = threading.Lock()
        self._lidar = LidarStatus(source=lidar_source, state=self._passive_state())
        self._camera = CameraStatus(source=camera_source)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="rigd-sensors", daemon=True)

    def _passive_state(self) -> str:
        if self.udp is not None:
            return "unknown"
        return "simulated" if parse_lidar(self.lidar_source).kind is LidarKind.SIM else "replay"

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()

    def snapshot(self) -> tuple[LidarStatus, CameraStatus]:
        capture = self.capture_figures()
        return capture if capture is not None else (self._lidar, self._camera)

    def _loop(self) -> None:
        while not self._stop.is_set():
            self._camera = probe_camera(self.camera_source)
            if self.udp is not None and self.lidar_lock.acquire(blocking=False):
                try:
                    self._lidar = probe_lidar(self.udp, self.listen_s)
                finally:
                    self.lidar_lock.release()
            self._stop.wait(self.poll_s)
