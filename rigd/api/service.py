"""The service's parts wired together: database, stores, job runner and sensor monitor, and their start/stop."""

from __future__ import annotations

import contextlib
import threading
from dataclasses import dataclass, field
from pathlib import Path

from rigd.api.calibration_result import ActivationBounds
from rigd.api.job_runner import JobRunner
from rigd.api.models import CameraStatus, LidarStatus
from rigd.api.sensors import SensorMonitor
from rigd.api.settings import Settings
from rigd.capture.config import RigSettings, load_settings
from rigd.store import Database, DataDirLock, JobStore, VersionStore
from rigd.store.datasets import DatasetCatalog
from rigd.store.db import utc_now
from rigd.version import software_version


@dataclass
class CaptureFigures:
    """The LiDAR figures a running capture reports, and its camera's state, shown by GET /status while it holds
    the sensors (the probe stands aside: it would call a simulated capture's camera absent)."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    current: tuple[LidarStatus, CameraStatus] | None = None

    def set(self, status: tuple[LidarStatus, CameraStatus] | None) -> None:
        with self.lock:
            self.current = status

    def get(self) -> tuple[LidarStatus, CameraStatus] | None:
        with self.lock:
            return self.current


@dataclass
class Service:
    settings: Settings
    lock: DataDirLock
    rig: RigSettings
    db: Database
    versions: VersionStore
    jobs: JobStore
    datasets: DatasetCatalog
    runner: JobRunner
    sensors: SensorMonitor
    capture_figures: CaptureFigures
    software_version: str
    started_at: str

    @property
    def data_dir(self) -> Path:
        return self.settings.data_dir

    def start(self) -> None:
        self.runner.start()
        self.sensors.start()

    def stop(self) -> None:
        """Jobs stopped, sensors stopped, the database closed and the data directory released, each even when the
        one before failed (a data directory deleted under the service fails the jobs' last records)."""
        with contextlib.ExitStack() as later:  # run last to first, each whatever happened before it
            later.callback(self.lock.release)
            later.callback(self.db.close)
            later.callback(self.sensors.stop)
            self.runner.shutdown()


def build_service(settings: Settings) -> Service:
    """Lock and open the data directory; jobs left unfinished by a previous run are marked failed (interrupted).
    DataDirLockedError if another service holds it."""
    rig = load_settings(settings.config)
    # Before anything reads the database: a second service must not fail the first one's jobs.
    lock = DataDirLock.acquire(settings.data_dir)
    try:
        return _open_service(settings, rig, lock)
    except BaseException:
        lock.release()
        raise


def _open_service(settings: Settings, rig: RigSettings, lock: DataDirLock) -> Service:
    db = Database(settings.data_dir / "rigd.db")
    jobs = JobStore(db, settings.data_dir / "jobs", min_free_bytes=int(settings.min_free_mb * 1e6))
    jobs.fail_unfinished("interrupted: the service stopped while the job was queued or running")
    versions = VersionStore(db)
    datasets = DatasetCatalog(settings.data_dir / "datasets")
    code_version = software_version()
    bounds = ActivationBounds(
        require_converged=settings.auto_activate_require_converged,
        min_pairs=settings.auto_activate_min_pairs,
        max_rotation_deg=settings.auto_activate_max_rotation_deg,
        max_translation_cm=settings.auto_activate_max_translation_cm,
    )
    figures = CaptureFigures()
    return Service(
        settings=settings,
        lock=lock,
        rig=rig,
        db=db,
        versions=versions,
        jobs=jobs,
        datasets=datasets,
        runner=JobRunner(jobs, versions, datasets, bounds, code_version, settings.max_queued_jobs, settings.workers),
        sensors=SensorMonitor(rig.camera_source, rig.lidar_source, settings.sensor_poll_s, figures.get),
        capture_figures=figures,
        software_version=code_version,
        started_at=utc_now(),
    )
