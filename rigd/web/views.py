"""What the operator page shows, read from the service as the open ``GET`` endpoints read it: the status, the
latest jobs with the verdicts they produced, a page of the newest versions, the datasets."""

from __future__ import annotations

from dataclasses import dataclass

from starlette.concurrency import run_in_threadpool

from rigd.api.models import DatasetOut, JobOut, RigOut, StatusOut
from rigd.api.rigs import recorded_rig, rig_words, same_rig
from rigd.api.routes.datasets import list_datasets
from rigd.api.routes.jobs import list_jobs
from rigd.api.routes.status import get_status
from rigd.api.service import Service
from rigd.report import verdict_of
from rigd.results import is_calibration
from rigd.store import ExtrinsicsVersion
from rigd.web.jobs_view import JobView
from rigd.web.versions_view import VersionView, version_view

JOBS_SHOWN = 15
VERSIONS_PAGE = 10  # versions on the page at first; "Show older" adds as many again


def job_views(jobs: list[JobOut], stored: dict[int, ExtrinsicsVersion], active: int | None) -> list[JobView]:
    views = []
    for job in jobs:
        version = stored.get(n) if (n := stored_version(job)) is not None else None
        if version is None:
            views.append(JobView(job, n, active_now=active))
            continue
        verdict = verdict_of(version.quality)
        views.append(JobView(job, n, version.status.value, verdict["status"] if verdict else "none", active))
    return views


def dataset_rig(d: DatasetOut) -> RigOut | None:
    """A listed dataset's rig (None: it cannot be read)."""
    return RigOut(camera=d.camera, lidar_model=d.lidar_model) if d.camera is not None else None


@dataclass(frozen=True)
class PageState:
    status: StatusOut
    jobs: list[JobView]
    versions: list[VersionView]  # newest first
    version_count: int
    default_view: VersionView | None  # the newest calibration: the viewer shows it until another is picked
    datasets: list[DatasetOut]
    active_rig: RigOut | None = None  # the active version's (None: none active, or not known)

    @property
    def capture(self) -> JobView | None:
        """The running (else the latest) capture job."""
        captures = [j for j in self.jobs if j.record.kind == "capture"]
        return next((j for j in captures if j.record.status == "running"), captures[0] if captures else None)

    @property
    def busy(self) -> bool:
        return any(j.record.status in ("queued", "running") for j in self.jobs)

    def fits_active(self, d: DatasetOut) -> bool:
        """Whether the active version may start (or be checked on) dataset ``d``: there is one, of ``d``'s rig."""
        return self.status.active_extrinsics is not None and same_rig(self.active_rig, dataset_rig(d))

    def other_rig(self, d: DatasetOut) -> str:
        """Why the active version does not fit ``d`` ("" when it does, or none is active)."""
        active = self.status.active_extrinsics
        if active is None or self.active_rig is None or self.fits_active(d):
            return ""
        return f"version {active.version} is of another rig ({rig_words(self.active_rig)})"


def stored_version(job: JobOut) -> int | None:
    """The version a calibration job stored, if any."""
    return job.result["version"] if job.result is not None and is_calibration(job.result) else None


@dataclass(frozen=True)
class _Read:
    jobs: list[JobView]
    versions: list[VersionView]
    version_count: int
    default_view: VersionView | None
    datasets: list[DatasetOut]
    active_rig: RigOut | None


def _read(service: Service, shown: int) -> _Read:
    jobs = list_jobs(service, JOBS_SHOWN, None, None)
    stored = service.versions.numbered({n for j in jobs if (n := stored_version(j)) is not None})
    active = service.versions.active()
    datasets = list_datasets(service)
    listed = {d.id: dataset_rig(d) for d in datasets}

    def rig(version: ExtrinsicsVersion) -> RigOut | None:  # recorded, else its dataset's as listed
        return recorded_rig(version) or (listed.get(version.dataset_id) if version.dataset_id else None)

    active_rig = rig(active) if active else None

    def view(version: ExtrinsicsVersion) -> VersionView:
        return version_view(version, active, rig(version), active_rig)

    newest_calibration = service.versions.newest_calibration()
    return _Read(job_views(jobs, stored, active.number if active else None),
                 [view(v) for v in service.versions.newest(shown)], service.versions.count(),
                 view(newest_calibration) if newest_calibration else None, datasets, active_rig)


async def page_state(service: Service, shown: int) -> PageState:
    """The page's state with the ``shown`` newest versions."""
    status = await get_status(service)
    read = await run_in_threadpool(_read, service, shown)
    return PageState(status, read.jobs, read.versions, read.version_count, read.default_view, read.datasets,
                     read.active_rig)
