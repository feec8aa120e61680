"""``GET /``: the operator page (docs/service.md), server-rendered from Jinja2 templates, and ``GET /ui/live``,
the same page's parts re-rendered for its script to swap in while jobs run.

The page reads what the open ``GET`` endpoints read and nothing else; its buttons call the JSON API from the
browser, with the bearer token the operator types when the service has one (kept in the tab's sessionStorage,
never sent to or rendered by the server in a page).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from fastapi import APIRouter, FastAPI
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from jinja2 import Environment, FileSystemLoader, StrictUndefined
from starlette.concurrency import run_in_threadpool

from calib.geometry import Transform
from calib.uncertainty import AXES, TO_DISPLAY, xi_of
from rigd.api.deps import ServiceDep
from rigd.api.models import DatasetOut, JobOut, StatusOut, VersionOut
from rigd.api.routes.datasets import list_datasets
from rigd.api.routes.extrinsics import list_versions
from rigd.api.routes.jobs import list_jobs
from rigd.api.routes.status import get_status
from rigd.api.service import Service

HERE = Path(__file__).resolve().parent.parent
TEMPLATES = Environment(loader=FileSystemLoader(HERE / "templates"), autoescape=True, undefined=StrictUndefined,
                        trim_blocks=True, lstrip_blocks=True)
PARTS = ("summary", "sensors", "capture", "datasets", "jobs", "versions")  # templates/_PART.html, one region each
JOBS_SHOWN = 15
# No inline script or style (the templates have none): an injected tag in any text shown could not run.
HEADERS = {
    "Content-Security-Policy": "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; "
                               "connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}

router = APIRouter(include_in_schema=False)


def install(app: FastAPI) -> None:
    """The page's router and its static files (``/static``: script, style sheet)."""
    app.include_router(router)
    app.mount("/static", StaticFiles(directory=HERE / "static"), name="static")


@dataclass(frozen=True)
class VersionView:
    """A version as the page shows it: its values, change against the active one and sigma per axis
    (roll, pitch, yaw deg; x, y, z cm; the change in the uncertainty's local axes, as ``rigd check``), its
    pairs with overlays and a multi-camera head's sensors (empty for one camera)."""

    record: VersionOut
    values: list[float]
    change: list[float] | None
    sigma: list[float | None] | None
    pairs: list[int]
    sensors: list[str]


def report_sensors(quality: dict[str, Any]) -> list[str]:
    """A head's sensors, in the dataset's order, as the version's report lists them per pair (the overlays were
    written per sensor under these names); empty for one camera or a version without pairs (manual)."""
    pairs = quality.get("pairs") or []
    per_sensor = pairs[0].get("edge_pixels_per_sensor") if pairs and isinstance(pairs[0], dict) else None
    return [str(name) for name in per_sensor] if isinstance(per_sensor, dict) else []


def version_views(versions: list[VersionOut]) -> list[VersionView]:
    """Newest first."""
    transforms = {v.number: Transform.from_matrix(np.asarray(v.T_camera_lidar.matrix)) for v in versions}
    active = next((v.number for v in versions if v.status == "active"), None)
    views = []
    for v in reversed(versions):
        values = [*v.T_camera_lidar.rpy_deg, *(np.asarray(v.T_camera_lidar.xyz_m) * 100.0)]
        change = None
        if active is not None and v.number != active:
            change = (xi_of(transforms[active].tau, transforms[v.number].tau) * TO_DISPLAY).tolist()
        sigma = [*v.uncertainty["rpy_deg"], *v.uncertainty["xyz_cm"]] if v.uncertainty else None
        pairs = [int(link.rsplit("/", 1)[1].removesuffix(".png")) for link in v.overlays]
        views.append(VersionView(v, [float(x) for x in values], change, sigma, pairs, report_sensors(v.quality)))
    return views


@dataclass(frozen=True)
class PageState:
    status: StatusOut
    jobs: list[JobOut]
    versions: list[VersionView]
    datasets: list[DatasetOut]

    @property
    def capture(self) -> JobOut | None:
        """The running (else the latest) capture job."""
        captures = [j for j in self.jobs if j.kind == "capture"]
        return next((j for j in captures if j.status == "running"), captures[0] if captures else None)

    @property
    def busy(self) -> bool:
        return any(j.status in ("queued", "running") for j in self.jobs)


async def page_state(service: Service) -> PageState:
    status = await get_status(service)
    jobs = await run_in_threadpool(list_jobs, service, JOBS_SHOWN, None, None)
    versions = await run_in_threadpool(list_versions, service)
    datasets = await run_in_threadpool(list_datasets, service)
    return PageState(status, jobs, version_views(versions), datasets)


def _context(service: Service, state: PageState) -> dict[str, Any]:
    rig = service.rig
    return {"state": state, "axes": AXES, "token_required": service.settings.token is not None,
            "sim_rig": rig.lidar_source.startswith("sim") and rig.camera_source.startswith("sim"),
            "capture_defaults": rig.capture}


def render_part(name: str, context: dict[str, Any]) -> str:
    return TEMPLATES.get_template(f"_{name}.html").render(context)


@router.get("/", response_class=HTMLResponse)
async def page(service: ServiceDep) -> HTMLResponse:
    context = _context(service, await page_state(service))
    html = TEMPLATES.get_template("page.html").render(context, parts={p: render_part(p, context) for p in PARTS})
    return HTMLResponse(html, headers=HEADERS)


@router.get("/ui/live")
async def live(service: ServiceDep) -> JSONResponse:
    """The page's regions, rendered now, and whether a job is queued or running (the script polls faster)."""
    state = await page_state(service)
    context = _context(service, state)
    return JSONResponse({"parts": {p: render_part(p, context) for p in PARTS}, "busy": state.busy},
                        headers=HEADERS)
