"""A dataset's captured pairs over HTTP, before any calibration: the image as captured (or narrowed for a
screen), a head's sensors, and the cloud from above coloured with the dataset's initial guess."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml
from api_helpers import App, simulated_dataset

from rigd.calibration.visuals import UNSEEN_BGR
from rigd.dataset import open_dataset
from rigd.simulate import write_simulated_dataset


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    data = tmp_path_factory.mktemp("pairs") / "data"
    plain = simulated_dataset(data, "plain")
    guessed = simulated_dataset(data, "guessed")  # the same pairs, with the truth as its initial guess
    rig = yaml.safe_load((guessed / "rig.yaml").read_text())
    truth = open_dataset(guessed).ground_truth
    rig["initial_guess"] = {"rpy_deg": truth.rpy_deg.tolist(), "xyz_m": truth.translation_m.tolist()}
    (guessed / "rig.yaml").write_text(yaml.safe_dump(rig))
    head = write_simulated_dataset(data / "datasets" / "head", "outdoor", 1, 5, width=160, height=200,
                                   progress=False, head=True)
    server = App(data).start()  # the routes that serve a dataset's pairs: rigd's app in this process
    yield server, {"plain": plain, "head": head}
    server.stop()


def decoded(content: bytes) -> np.ndarray:
    image = cv2.imdecode(np.frombuffer(content, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None
    return image


def test_the_image_as_captured_and_narrowed(served):
    server, roots = served
    with server.client() as client:
        detail = client.get("/datasets/plain").json()
        assert detail["sensors"] == [] and [p["number"] for p in detail["pairs"]] == [0, 1]
        response = client.get("/datasets/plain/pairs/1/image")
        assert response.status_code == 200 and response.headers["content-type"] == "image/png"
        assert response.content == (roots["plain"] / "pairs" / "0001" / "image.png").read_bytes()
        small = client.get("/datasets/plain/pairs/1/image", params={"width": 128})
        assert decoded(small.content).shape == (64, 128, 3)
        assert client.get("/datasets/plain/pairs/2/image").status_code == 404
        missing = client.get("/datasets/plain/pairs/0/image", params={"sensor": "cam0"})
        assert missing.status_code == 404 and "no sensor cam0" in missing.json()["detail"]
        assert client.get("/datasets/nothing/pairs/0/image").status_code == 404
        assert client.get("/datasets/plain/pairs/0/image", params={"width": 10}).status_code == 422


def test_a_heads_images_by_sensor(served):
    server, roots = served
    views = list(open_dataset(roots["head"]).views)
    with server.client() as client:
        assert client.get("/datasets/head").json()["sensors"] == views
        folder = roots["head"] / "pairs" / "0000" / "images"
        for name in (views[2], None):
            params = {"sensor": name} if name else {}
            response = client.get("/datasets/head/pairs/0/image", params=params)
            assert response.status_code == 200
            assert response.content == next(folder.glob(f"{name or views[0]}.*")).read_bytes()


def unseen_share(image: np.ndarray) -> float:
    """The share of the drawn points (pixels brighter than the background and grid) in the unseen grey."""
    points = image.max(axis=2) > 60
    return float(np.all(image[points] == UNSEEN_BGR, axis=1).mean())


def test_the_cloud_from_above_takes_the_images_colours_with_a_guess(served):
    server, _ = served
    with server.client() as client:
        plain = client.get("/datasets/plain/pairs/0/cloud.png")
        guessed = client.get("/datasets/guessed/pairs/0/cloud.png")
        small = client.get("/datasets/guessed/pairs/0/cloud.png", params={"width": 300})
        assert client.get("/datasets/plain/pairs/5/cloud.png").status_code == 404
    assert plain.headers["content-type"] == "image/png"
    assert decoded(plain.content).shape == decoded(guessed.content).shape == (900, 900, 3)
    assert decoded(small.content).shape == (300, 300, 3)
    assert unseen_share(decoded(plain.content)) > 0.9  # no guess: every point grey
    assert unseen_share(decoded(guessed.content)) < 0.1  # the truth: nearly every point lands in the image
