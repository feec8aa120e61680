"""What the page needs from the API, through the in-process application: a version's rig (a start from the
active version, and a check of it, refused for a dataset of another rig), the active version's verdict in
/status, datasets said by their id in errors, and overlays as screen-sized JPEG."""

from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest
import yaml
from api_helpers import App, simulated_dataset

from calib.geometry import Transform
from rigd.api.rigs import rig_record
from rigd.dataset import open_dataset
from rigd.store import JobKind, JobStatus, NewVersion


def quality(status: str, weak: list[str]) -> dict:
    """A calibration's stored quality, as small as the API's schema takes it."""
    return {"final_cost": 1.0, "converged": True, "levels": [], "pairs": [{"edge_pixels": 10, "edge_points": 10}],
            "wall_time_s": 1.0, "pairs_used": 1,
            "uncertainty": {"rpy_deg": [0.1] * 3, "xyz_cm": [1.0] * 3, "covariance": None, "weakest": "x"},
            "verdict": {"status": status, "weak_axes": weak, "reasons": ["x known to ±3 cm (needs ±2 cm)"]},
            "method": {"name": "gmm", "why": "the default for an equirectangular camera"}}


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    """"field" (a 256x128 panorama) and "wide", the same with its rig.yaml's camera twice as wide (another rig);
    version 1, calibrated on field (its rig recorded), weak in x, active, with an overlay of pair 0."""
    data = tmp_path_factory.mktemp("rigs") / "data"
    field = simulated_dataset(data, "field", pairs=1)
    wide = data / "datasets" / "wide"
    shutil.copytree(field, wide)
    rig = yaml.safe_load((wide / "rig.yaml").read_text())
    rig["camera"].update(width=512, height=256)
    (wide / "rig.yaml").write_text(yaml.safe_dump(rig))
    app = App(data).start()
    service = app.service
    job = service.jobs.create(JobKind.CALIBRATE, {"dataset": "field"}, "done")
    service.jobs.finish(job.id, JobStatus.FAILED, "failed", error=f"{field}/pairs/0000/cloud.pcd: truncated")
    overlays = service.jobs.job_dir(job.id) / "calibration" / "overlays"
    overlays.mkdir(parents=True)
    rng = np.random.default_rng(0)
    picture = cv2.GaussianBlur(rng.integers(0, 255, (400, 800, 3), dtype=np.uint8), (0, 0), 4)
    cv2.imwrite(str(overlays / "0000_after.png"), picture)
    service.versions.add(NewVersion(
        T_camera_lidar=open_dataset(field).ground_truth or Transform.identity(), quality=quality("weak", ["x"]),
        method="gmm", parameters={"dataset": "field", "rig": rig_record(open_dataset(field)), "pair_numbers": [0]},
        code_version="test", dataset_id="field", job_id=job.id), lambda change: True)
    yield app
    app.stop()


def test_the_active_version_starts_and_checks_only_datasets_of_its_rig(app):
    with app.client() as client:
        version = client.get("/extrinsics/versions/1").json()
        assert version["rig"] == {"camera": {"model": "equirectangular", "width": 256, "height": 128},
                                  "lidar_model": "VLP-16"}
        refused = client.post("/calibrate", json={"dataset": "wide", "init": "active"})
        assert refused.status_code == 409
        assert refused.json()["detail"] == (
            "the active version 1 was calibrated on another rig (equirectangular 256×128, VLP-16, dataset field) "
            "than dataset wide (equirectangular 512×256, VLP-16): start from the dataset's own guess (init 'rig') "
            "or a global search (init 'search')")
        check = client.post("/check", json={"dataset": "wide", "against": "active"})
        assert check.status_code == 409 and "calibrate dataset wide instead" in check.json()["detail"]
        same = client.post("/calibrate", json={"dataset": "field", "init": "active"})
        assert same.status_code == 202, same.text
        params = same.json()["params"]
        assert params["rig"] == version["rig"]  # kept with its job, and so with the version it stores
        assert params["method"]["name"] == "gmm" and "default" in params["method"]["why"]  # resolved, and why
        client.delete(f"/jobs/{same.json()['id']}")


def test_status_names_the_active_versions_verdict(app):
    with app.client() as client:
        active = client.get("/status").json()["active_extrinsics"]
        assert (active["version"], active["verdict"], active["weak_axes"]) == (1, "weak", ["x"])
        page = client.get("/").text
    assert 'id="active-verdict">weak</span>' in page and "x not known" in page


def test_errors_name_the_dataset_not_the_servers_path(app):
    with app.client() as client:
        job = client.get("/jobs/1").json()
        assert job["error"] == "dataset field's pairs/0000/cloud.pcd: truncated"
        assert str(app.data_dir / "datasets") not in client.get("/").text


def test_overlays_are_sent_screen_sized_as_jpeg(app):
    with app.client() as client:
        png = client.get("/extrinsics/versions/1/overlays/0.png", params={"width": 400})
        jpeg = client.get("/extrinsics/versions/1/overlays/0.png", params={"width": 400, "format": "jpeg"})
        full = client.get("/extrinsics/versions/1/overlays/0.png", params={"format": "jpeg"})
    assert png.headers["content-type"] == "image/png" and jpeg.headers["content-type"] == "image/jpeg"
    shown = cv2.imdecode(np.frombuffer(jpeg.content, np.uint8), cv2.IMREAD_COLOR)
    assert shown.shape == (200, 400, 3) and len(jpeg.content) < len(png.content) / 2
    assert "max-age" in jpeg.headers["cache-control"]  # a version's overlays never change
    assert cv2.imdecode(np.frombuffer(full.content, np.uint8), cv2.IMREAD_COLOR).shape == (400, 800, 3)


def test_the_rig_files_guess_starts_only_datasets_of_its_rig(app):
    """The service's rig file (a 256x128 panorama) has a guess: "field" starts from it, "wide" (another camera
    size) does not, and searches instead, as the page's row says before it is sent."""
    with app.client() as client:
        for dataset, guessed in (("field", True), ("wide", False)):
            job = client.post("/calibrate", json={"dataset": dataset, "init": "rig"}).json()
            assert (job["params"]["request"]["initial"] is not None) == guessed, job["params"]
            client.delete(f"/jobs/{job['id']}")
        page = client.get("/").text
    assert 'data-dataset="field" data-pairs="1" data-fits-active="true" data-other-rig="" data-guess="true"' in page
    assert 'data-dataset="wide" data-pairs="1" data-fits-active="false"' in page and 'data-guess="false"' in page
