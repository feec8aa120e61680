"""``GET /``: the operator page (docs/service.md), server-rendered from Jinja2 templates, and ``GET /ui/live``,
the page's parts rendered again for its script, sent only where they changed.

The page reads what the open ``GET`` endpoints read and nothing else; its buttons call the JSON API from the
browser, with the bearer token the operator types when the service has one (kept in the tab's sessionStorage,
never sent to or rendered by the server in a page).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, FastAPI, Query
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from jinja2 import Environment, FileSystemLoader, StrictUndefined

from calib.methods import FIELD_METHODS, METHODS
from calib.uncertainty import AXES
from rigd.api.deps import ServiceDep
from rigd.api.models import DatasetOut
from rigd.api.rigs import fits_rig_file
from rigd.api.service import Service
from rigd.dataset.records import MAX_LEVER_ARM_M
from rigd.store.datasets import DATASET_ID_RULE
from rigd.web.jobs_view import capture_words
from rigd.web.views import VERSIONS_PAGE, PageState, dataset_rig, page_state
from rigd.web.words import page_words

HERE = Path(__file__).resolve().parent
TEMPLATES = Environment(loader=FileSystemLoader(HERE / "templates"), autoescape=True, undefined=StrictUndefined,
                        trim_blocks=True, lstrip_blocks=True)
TEMPLATES.globals["page_words"] = page_words  # the page's wording of rigd's texts, in every part
PARTS = ("summary", "sensors", "capture", "datasets", "jobs", "versions")  # templates/_PART.html, one region each
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


def _context(service: Service, state: PageState) -> dict[str, Any]:
    rig = service.rig

    def has_guess(d: DatasetOut) -> bool:
        """Whether dataset ``d`` has a guess to start from: its rig.yaml's, or the rig file's for its rig."""
        own = dataset_rig(d)
        return d.initial_guess is not None or (rig.initial_guess is not None and own is not None
                                                and fits_rig_file(rig, own))

    return {"state": state, "axes": AXES, "token_required": service.settings.token is not None,
            "sim_rig": rig.lidar_source.startswith("sim") and rig.camera_source.startswith("sim"),
            "capture_defaults": rig.capture, "rig_guess": rig.initial_guess, "versions_page": VERSIONS_PAGE,
            "lever_arm_cm": MAX_LEVER_ARM_M * 100.0, "dataset_id_rule": DATASET_ID_RULE, "capture_words": capture_words,
            "has_guess": has_guess,
            "methods": [(m.value, METHODS[m].label) for m in FIELD_METHODS]}


def render_parts(context: dict[str, Any]) -> dict[str, str]:
    return {name: TEMPLATES.get_template(f"_{name}.html").render(context) for name in PARTS}


def digest(html: str) -> str:
    """A short hash of a part's HTML: the page sends back the ones it shows, /ui/live sends only the others."""
    return hashlib.blake2b(html.encode(), digest_size=8).hexdigest()


@router.api_route("/", methods=["GET", "HEAD"], response_class=HTMLResponse)
async def page(service: ServiceDep) -> HTMLResponse:
    context = _context(service, await page_state(service, VERSIONS_PAGE))
    parts = render_parts(context)
    html = TEMPLATES.get_template("page.html").render(context, parts=parts,
                                                      hashes={name: digest(p) for name, p in parts.items()})
    return HTMLResponse(html, headers=HEADERS)


def known_hashes(have: str) -> dict[str, str]:
    """``summary:HASH,jobs:HASH,...`` (what the page shows) as a mapping; malformed items are ignored."""
    items = (item.partition(":") for item in have.split(",") if item)
    return {name: value for name, _, value in items if name in PARTS}


@router.get("/ui/live")
async def live(service: ServiceDep,
               shown: Annotated[int, Query(ge=1, le=100_000, description="versions the page shows")] = VERSIONS_PAGE,
               have: Annotated[str, Query(max_length=1000, description="part:hash,... the page has")] = ""
               ) -> JSONResponse:
    """The parts whose HTML differs from what the page has, every part's hash, and whether a job is queued or
    running (the script then polls faster)."""
    state = await page_state(service, shown)
    parts = render_parts(_context(service, state))
    hashes = {name: digest(html) for name, html in parts.items()}
    known = known_hashes(have)
    changed = {name: html for name, html in parts.items() if known.get(name) != hashes[name]}
    return JSONResponse({"parts": changed, "hashes": hashes, "busy": state.busy}, headers=HEADERS)
