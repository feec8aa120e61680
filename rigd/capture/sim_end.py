"""When a simulated rig has given every place it will: a capture that follows one ends rather than waiting for a
new place for ever (:class:`SimRigEndedError`, raised by the capture loop with :meth:`SimRigEnd.message`)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

from drivers.sim.motion import MotionRigSpec
from rigd.capture.records import CaptureRequest
from rigd.capture.specs import LidarKind, parse_camera, parse_lidar

# The simulated rig stands still_seconds + this at each place: time for the gate to see the drive's slow end and
# for the pair; the camera renders each stop's view before the rig gets there (drivers.sim.stream), so a frame
# exposed in the still window arrives within a frame period. With 6 s the demo took 84 s, with 3 s 62 s (quiet).
SIM_STOP_MARGIN_S = 3.0
SIM_MOVE_S = 2.0
# The simulated rig stands at its last place for good. Once it has stood there as long as a stop lasts (or the
# gate's --still-seconds, if longer) and this much more, with pairs still missing, no pair can come: the capture
# ends with SimRigEndedError rather than waiting for a new place for ever. At once if the last place has its pair.
SIM_END_GRACE_S = 5.0


def sim_stops(pairs: int) -> int:
    """Places for a simulated rig that should yield ``pairs`` pairs: twice as many plus spares, since a stop
    whose frame rendered too slowly is skipped, and the rig never leaves its last place."""
    return 2 * pairs + 4


@dataclass(frozen=True)
class SimRigEnd:
    """When the simulated rig a capture follows has given all the places it will: it reaches its last place at
    ``last_stop_host_s`` (UNIX s; drivers.sim.motion.Trajectory.stop_interval: stop ``i`` begins ``i`` legs
    after the rig's start) and stands there for good; after ``deadline_host_s`` no pair is to be had there."""

    source: str  # the option that names the rig, as given: "--lidar sim", "--lidar sim:FILE", "--camera sim:FILE"
    file: Path | None  # its sim rig file (None: the rig capture builds for --lidar sim)
    in_process: bool  # run by this capture (--lidar sim[:FILE]), not followed elsewhere (--camera sim:FILE)
    stops: int  # its places
    places: int  # of which the capture could use: from the one the rig was at or driving to when it began
    asked: int  # pairs the dataset should have (--n)
    wanted: int  # of which this capture was to add
    still_s: float
    move_s: float
    last_stop_host_s: float
    deadline_host_s: float

    @classmethod
    def of(cls, spec: MotionRigSpec | None, request: CaptureRequest, existing: int) -> SimRigEnd | None:
        if spec is None or spec.start_host_s is None:  # a real rig: people move it on for as long as it takes
            return None
        lidar = parse_lidar(request.lidar)
        in_process = lidar.kind is LidarKind.SIM
        file = lidar.path if in_process else parse_camera(request.camera).path
        source = f"--lidar {request.lidar}" if in_process else f"--camera {request.camera}"
        leg_s = spec.still_s + spec.move_s
        last_stop = spec.start_host_s + (spec.stops - 1) * leg_s
        began = time.time()
        passed = min(max(math.floor((began - spec.start_host_s) / leg_s), 0), spec.stops - 1)  # legs already done
        stand_s = max(spec.still_s, request.still_seconds)  # the gate may need longer than the rig's stops
        return cls(source, file, in_process, spec.stops, spec.stops - passed, request.n, request.n - existing,
                   spec.still_s, spec.move_s, last_stop, max(last_stop, began) + stand_s + SIM_END_GRACE_S)

    def message(self, now: float, done: int, written: int, out: Path) -> str:
        stood_s = max(now - self.last_stop_host_s, 0.0)
        kept = f"{written} written by this run, complete" if written else "none written by this run"
        head = (f"the simulated rig ({self.source}) has stopped at all its {self.stops} places and stands at the "
                f"last one for good ({stood_s:.1f} s so far): {out} has {done} of the {self.asked} pairs asked "
                f"({kept})")
        if self.places < self.wanted:
            where = "its sim rig file" if self.file is None else self.file
            more = f"{'give it' if self.in_process else 'restart it with'} more places (stops in {where})"
            return f"{head}; it has too few places for the {self.wanted} pairs missing: {more}, or ask for fewer (--n)"
        if self.file is None:
            fix = ("lengthen its stops with a larger --still-seconds (it stands --still-seconds + "
                   f"{SIM_STOP_MARGIN_S:g} s at each place)")
        elif self.in_process:
            fix = (f"lengthen its stops (still_s) or shrink its panorama (width, height) in {self.file} (for `rigd "
                   "demo`: a smaller --width)")
        else:
            fix = f"restart it with longer stops (still_s) or a smaller panorama (width, height) in {self.file}"
        rerun = "; rerunning the same command adds the missing pairs at new places" if self.file is None else ""
        missed = max(self.places - written, 0)
        return (f"{head}; {missed} of its stops gave no pair: the simulated camera renders too slowly for this "
                f"machine's load (each stop's view must be rendered within a leg: {self.still_s:g} s "
                f"standing + {self.move_s:g} s driving); close other jobs, or {fix}{rerun}")

