"""Parts of the operator page rendered without a browser: the Sensors card during a capture and its times, a
failed capture's error shown once, and which changes against the active version stand out."""

import re
from html import unescape
from pathlib import Path

from rigd.api.models import CameraStatus, JobOut, LidarStatus
from rigd.api.routes.capture import capture_sensors
from rigd.capture import CaptureRequest, CaptureStatus
from rigd.web.jobs_view import JobView
from rigd.web.routes import TEMPLATES
from rigd.web.versions_view import stands_out


def _text(html: str) -> str:
    return " ".join(unescape(re.sub(r"<[^>]+>", " ", html)).split())


class _Sensors:
    def __init__(self, lidar: LidarStatus, camera: CameraStatus) -> None:
        self.lidar, self.camera = lidar, camera


def _render_sensors(lidar: LidarStatus, camera: CameraStatus) -> str:
    class Status:
        sensors = _Sensors(lidar, camera)

    class State:
        status = Status()

    return TEMPLATES.get_template("_sensors.html").render({"state": State()})


def test_a_simulated_capture_shows_its_camera_delivering_not_absent():
    """The rig file's camera is the USB one, absent; a capture from the simulated rig has frames: the card shows
    the capture's camera while it runs, and the time both were last seen."""
    request = CaptureRequest(out=Path("/data/datasets/s"), n=4, lidar="sim", camera="sim")
    status = CaptureStatus(state="moving", pairs_done=1, pairs_wanted=4, still_for_s=0.0, packet_rate_hz=754.0,
                           packets_lost=0, message="move to the next place")
    job = type("Job", (), {"id": 12})()
    lidar, camera = capture_sensors(request, job, status)
    shown = _text(_render_sensors(lidar, camera))
    assert "absent" not in shown and "Camera simulated sim" in shown
    assert "in use by capture job 12: 1 of 4 pairs taken from the simulated rig" in shown
    assert camera.checked_at == lidar.checked_at


def test_checked_is_the_newer_of_the_sensors_times_as_a_local_time():
    """The LiDAR probed long ago, the camera now: "checked" does not jump back to the older one; its time is
    marked for the page to show in local time (UTC until then)."""
    lidar = LidarStatus(source="udp", state="ok", checked_at="2026-11-27T10:00:00.000+00:00")
    camera = CameraStatus(source="sdk", present=True, checked_at="2026-11-27T10:00:30.000+00:00")
    for a, b in ((lidar, camera), (lidar.model_copy(update={"checked_at": camera.checked_at}),
                                   camera.model_copy(update={"checked_at": lidar.checked_at}))):
        html = _render_sensors(a, b)
        assert '<time datetime="2026-11-27T10:00:30.000+00:00" data-local="time">' in html
    long_path = CameraStatus(source="sdk", present=True, warnings=["/sys/bus/usb/devices/" + "x" * 120])
    assert "x" * 120 in _render_sensors(lidar, long_path)  # wrapped by the style sheet (dl.grid dd)


def test_a_failed_capture_shows_its_error_once_under_capture():
    error = "camera: no SDK layout at /etc/rigd/ladybug_layout.yaml: install FLIR's Ladybug SDK ..."
    job = JobOut(id=4, kind="capture", status="failed", stage="failed", fraction=0.0, created_at="t", started_at="t",
                 finished_at="t", params={"dataset": "s", "n": 4}, result=None, result_link=None, error=error,
                 log_tail=[])

    class State:
        jobs = [JobView(job)]
        capture = JobView(job)

    class Status:
        sensors = _Sensors(LidarStatus(source="udp", state="ok"), CameraStatus(source="sdk"))

    State.status = Status()
    shown = _text(TEMPLATES.get_template("_capture.html").render({"state": State(), "capture_words": None}) +
                  TEMPLATES.get_template("_jobs.html").render({"state": State()}))
    assert shown.count("no SDK layout") == 1 and "its error is shown under Capture" in shown
    assert shown.count("failed") == 2  # the two badges, not the stage "failed" again


def test_only_a_change_beyond_the_verdicts_sigma_stands_out():
    sigma = [0.1, 0.1, 0.1, 1.0, 1.0, 1.0]
    assert stands_out([0.3, 0.2, 0.0, 3.0, -2.0, 0.0], sigma) == [True, False, False, True, False, False]
    assert stands_out([0.5, 0.0, 0.0, 3.0, 0.001, -0.004], None) == [True, False, False, True, False, False]
    assert not any(stands_out([0.0] * 6, sigma))
