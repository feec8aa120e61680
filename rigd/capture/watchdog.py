"""What ends a capture that waits for data that is not coming: a camera silent for longer than the silence timeout
(or the start-up allowance before its first frame), and a simulated rig that has given every place it will."""

from __future__ import annotations

import time
from pathlib import Path

from rigd.capture.errors import SensorSilenceError, SimRigEndedError
from rigd.capture.records import CaptureRequest
from rigd.capture.sim_end import SimRigEnd
from rigd.capture.sources import Sources
from rigd.capture.specs import CameraKind, parse_camera

# Before its first data a sensor may take this long (the SDK starts the camera, the simulator's sensors start
# as processes and render a first frame); after it, silence_timeout_s applies.
STARTUP_S = 15.0


class Watchdog:
    """The sensors of ``sources`` for a capture of ``request`` into a dataset that had ``existing`` pairs."""

    def __init__(self, request: CaptureRequest, sources: Sources, existing: int) -> None:
        self.request = request
        self.camera = sources.camera
        self.sim_end = SimRigEnd.of(sources.sim_spec, request, existing)
        self.last_place_taken = False  # a pair at the simulated rig's last place: it gives no other

    def silence_limit(self, any_data: bool) -> float:
        """The longest silence of a sensor that has (``any_data``) or has not yet sent data."""
        return self.request.silence_timeout_s if any_data else max(self.request.silence_timeout_s, STARTUP_S)

    def check_camera(self) -> None:
        silence = self.camera.seconds_since_frame()
        if silence is not None and silence[0] > max(self.silence_limit(silence[1]), self.camera.frame_gap_s):
            check = ("its process is stopped or hung" if parse_camera(self.request.camera).kind is CameraKind.SIM
                     else "check the camera's power and USB 3 link (rigd camera info)")
            raise SensorSilenceError(f"no camera frame from {self.camera.describe} for {silence[0]:.1f} s: {check}")

    def pair_taken(self, frame_t: float) -> None:
        """A pair of a frame at host time ``frame_t`` (s) was written."""
        if self.sim_end is not None and frame_t >= self.sim_end.last_stop_host_s:
            self.last_place_taken = True

    def check_sim_end(self, done: int, written: int, out: Path) -> None:
        """End a capture whose simulated rig can give no more pairs: it has stood at its last place longer than a
        stop lasts, or that place already has its pair, and the dataset is not complete (``done`` pairs, of which
        this run ``written``)."""
        end = self.sim_end
        if end is None or done >= self.request.n:
            return
        now = time.time()
        if self.last_place_taken or now > end.deadline_host_s:
            raise SimRigEndedError(end.message(now, done, written, out))
