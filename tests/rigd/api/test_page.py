"""The operator page (GET /, rigd/web) in a real headless Chromium (Debian's ``chromium`` and ``chromium-driver``,
driven by Selenium) against a real ``rigd serve``: a fresh install's first capture and calibration, captured pairs
looked at before calibrating, the verdict a job produced, activation confirmed with its reasons, the advice's
actions and calibration options, every reason of a check, messages that follow the job, the overlays' before/after
switch with zoom and pan at full resolution, versions paged with only changed parts sent, the banner while the
service does not answer, the token, a head's sensors, the layout at a phone's width, and no console errors.
Without the two packages the tests are skipped, reason printed (``apt-get install chromium chromium-driver``);
with ``RIGD_REQUIRE_BROWSER=1`` (.ci/run) they fail.

Screenshots go to the test's tmp dir, or to ``RIGD_PAGE_FIGURES`` (docs/figures/ holds a set made so).
The page's load time (navigation start to the load event) is printed: ``pytest -s tests/rigd/api/test_page.py``.
"""

from __future__ import annotations

import inspect
import os
import re
import signal
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from api_helpers import Server, perturbed_truth, simulated_dataset, wait_job
from selenium import webdriver
from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.chrome.service import Service as DriverService
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.actions.wheel_input import ScrollOrigin
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from rigd.capture.engine import CaptureState
from rigd.simulate import write_simulated_dataset

# Debian's packages (.ci/run installs them): browser and driver come from one source package, so they match.
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
INSTALL_BROWSER = "sudo apt-get install chromium chromium-driver"
REQUIRE_BROWSER = "RIGD_REQUIRE_BROWSER"
TOKEN = "correct-horse-battery-staple"
DESKTOP = (1280, 900)
PHONE = (360, 740)
TONE = {"trusted": "ok", "ok": "ok", "weak": "warn", "unknown": "warn", "failed": "bad", "drifted": "bad"}


@pytest.fixture(scope="module")
def browser():
    missing = [str(p) for p in (CHROMIUM, CHROMEDRIVER) if not p.exists()]
    if missing:
        reason = (f"{', '.join(missing)} not found: the operator page's test needs Debian's Chromium and its driver: "
                  f"{INSTALL_BROWSER} (.ci/run does)")
        if os.environ.get(REQUIRE_BROWSER):  # .ci/run installed them: without them the page would go untested
            pytest.fail(f"{reason}; {REQUIRE_BROWSER} is set, so this is a failure, not a skip")
        pytest.skip(reason)  # listed with its reason in pytest's summary (-rs, the project's addopts)
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                f"--window-size={DESKTOP[0]},{DESKTOP[1]}"):
        options.add_argument(arg)  # no sandbox: CI runs as root, where Chromium refuses its sandbox
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=DriverService(str(CHROMEDRIVER)))
    yield driver
    driver.quit()


@pytest.fixture
def figures(tmp_path):
    target = Path(os.environ.get("RIGD_PAGE_FIGURES") or tmp_path)
    target.mkdir(parents=True, exist_ok=True)
    return target


# -- helpers ----------------------------------------------------------------------------------------------------
def console_errors(driver, allowed: tuple[str, ...] = ()) -> list[str]:
    """SEVERE console entries since the last call (the log is drained), except those naming ``allowed``."""
    return [e["message"] for e in driver.get_log("browser")
            if e["level"] == "SEVERE" and not any(a in e["message"] for a in allowed)]


def load(driver, url: str) -> float:
    """Open ``url`` and return its load time (s): navigation start to the end of the load event."""
    driver.get(url)
    until(driver, 10, lambda d: d.execute_script(
        "const n = performance.getEntriesByType('navigation')[0]; return n && n.loadEventEnd > 0;"))
    return driver.execute_script("return performance.getEntriesByType('navigation')[0].loadEventEnd") / 1000.0


def until(driver, timeout_s: float, condition):
    """Wait for ``condition(driver)``; elements the page replaced meanwhile are looked up again."""
    return WebDriverWait(driver, timeout_s, ignored_exceptions=(StaleElementReferenceException,)).until(condition)


def texts(driver, css: str) -> list[str]:
    """The texts of the elements matching ``css``, read again if the page swapped them meanwhile."""
    for _ in range(5):
        try:
            return [e.text for e in driver.find_elements(By.CSS_SELECTOR, css)]
        except StaleElementReferenceException:
            continue
    raise AssertionError(f"{css} kept changing under the test")


def text(driver, css: str) -> str:
    """The text of the first element matching ``css`` ("" if none)."""
    return next(iter(texts(driver, css)), "")


def attr(driver, css: str, name: str) -> str | None:
    return driver.execute_script("const e = document.querySelector(arguments[0]); return e && e.getAttribute("
                                 "arguments[1]);", css, name)


def click(driver, css: str) -> None:
    until(driver, 10, lambda d: d.find_element(By.CSS_SELECTOR, css).is_enabled())
    for _ in range(5):  # the element may be replaced by a refresh between finding and clicking it
        try:
            element = driver.find_element(By.CSS_SELECTOR, css)
            driver.execute_script("arguments[0].scrollIntoView({block: 'center'})", element)
            element.click()
            return
        except StaleElementReferenceException:
            continue
    raise AssertionError(f"could not click {css}")


def watch(driver, css: str, done, timeout_s: float) -> list[str]:
    """The distinct texts ``css`` showed until ``done(text)`` (polled every 0.2 s)."""
    seen: list[str] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        now = text(driver, css)
        if now and (not seen or seen[-1] != now):
            seen.append(now)
        if now and done(now):
            return seen
        time.sleep(0.2)
    raise AssertionError(f"{css} did not finish in {timeout_s} s; it showed {seen}")


def finished(driver, css: str) -> bool:
    return attr(driver, css, "data-status") in ("succeeded", "failed", "cancelled")


def screenshot(driver, path: Path, size: tuple[int, int], mobile: bool) -> None:
    """The whole page at viewport ``size`` (CSS px), emulated as a phone when ``mobile``."""
    width, height = size
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": mobile})
    driver.execute_script("window.scrollTo(0, 0)")
    time.sleep(0.5)  # layout and images after the resize
    full = driver.execute_script("return document.documentElement.scrollHeight")
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": full, "deviceScaleFactor": 1, "mobile": mobile})
    time.sleep(0.5)
    until(driver, 10, images_loaded)
    driver.save_screenshot(str(path))
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": mobile})


def images_loaded(driver, ids: tuple[str, ...] = ("lens-after", "ov-closeup", "ov-cloud")) -> bool:
    return driver.execute_script(
        "return arguments[0].every(id => { const i = document.getElementById(id);"
        " return i.closest('[hidden]') || (i.complete && i.naturalWidth > 0); })", list(ids))


def lens_state(driver) -> dict:
    return driver.execute_script(
        "const l = document.getElementById('lens'), b = document.getElementById('lens-before'),"
        " a = document.getElementById('lens-after');"
        "return {zoom: Number(l.dataset.zoom), full: l.dataset.full, stage: l.dataset.stage,"
        " before: {src: b.getAttribute('src') || '', hidden: b.hidden, transform: b.style.transform},"
        " after: {src: a.getAttribute('src') || '', hidden: a.hidden, transform: a.style.transform,"
        "         natural: a.naturalWidth}, label: document.getElementById('zoom-label').textContent};")


def translate(transform: str) -> tuple[float, float]:
    x, y = re.search(r"translate\((-?[\d.]+)px, (-?[\d.]+)px\)", transform).groups()
    return float(x), float(y)


def message(driver) -> tuple[str, str]:
    """The top message's text and tone (its class: ok, warn, bad, or empty)."""
    return text(driver, "#message"), attr(driver, "#message", "class") or ""


# -- a fresh install, the whole loop ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """A fresh install (no version) with one simulated dataset, "field" (2 pairs, 256x128)."""
    data = tmp_path_factory.mktemp("page") / "data"
    simulated_dataset(data, "field")
    server = Server(data).start()
    yield server
    server.stop()


def test_page_capture_in_the_clis_words(browser, server, figures):
    """A capture of 2 pairs from the simulated rig, started from the page: its progress in rigd capture's words
    (no state names), live, and the message following it to its end."""
    load(browser, server.url + "/")
    assert browser.title == "rigd"
    assert console_errors(browser) == []
    assert text(browser, '[data-part="sensors"]').startswith("LiDAR")
    browser.find_element(By.NAME, "dataset").send_keys("captured")
    click(browser, "#capture-form button[type=submit]")
    done = lambda t: finished(browser, "#capture-job")  # noqa: E731
    receiving = re.compile(r"[1-9][0-9]* packets/s")
    shown = watch(browser, "#capture-job", lambda t: bool(receiving.search(t)) or done(t), 120)
    assert "running" in shown[-1] and receiving.search(shown[-1]) and "still for" in shown[-1], shown  # live
    browser.save_screenshot(str(figures / "page-capturing.png"))
    shown += watch(browser, "#capture-job", done, 120)
    assert "succeeded" in shown[-1] and "2 pairs written" in shown[-1], shown
    stages = [s for t in shown for s in re.findall(r"\d+/2 pairs: .*", t)]
    assert stages, shown  # the pair count and what to do, live
    internal = [s.value for s in CaptureState if "_" in s.value]
    assert not [t for t in shown if any(name in t for name in internal)], shown
    assert not any(name.replace("_", " ") in t for t in shown for name in internal), shown
    until(browser, 10, lambda d: "job 1 done: 2 pairs written" in message(d)[0])
    assert message(browser) == ("Capture into captured: job 1 done: 2 pairs written, 2 in the dataset", "ok")
    until(browser, 10, lambda d: "captured" in text(d, '[data-part="datasets"]'))
    assert "2 pairs" in text(browser, '[data-dataset="captured"]')
    assert console_errors(browser) == []


def test_page_calibrate_check_activate(browser, server, figures):
    first_load_s = load(browser, server.url + "/")
    assert console_errors(browser) == []
    # A fresh install has no active version: calibrating starts from the rig file (or the global search).
    assert "none" in text(browser, '[data-part="summary"]')
    assert browser.find_element(By.ID, "init-select").get_attribute("value") == "rig"
    assert not browser.find_element(By.CSS_SELECTOR, '#init-select option[value="active"]').is_enabled()

    captured_pairs_before_calibrating(browser, server)
    v1 = first_calibration(browser, server)
    before_after_zoom_and_pan(browser, server, v1)
    activate_with_confirmation(browser, server, v1)
    advice_and_options(browser, server, v1)
    manual_version_and_change(browser, server)
    check_with_every_reason(browser, server)

    assert console_errors(browser) == []
    loaded_s = load(browser, server.url + "/")  # with datasets, jobs and versions to render
    until(browser, 10, images_loaded)
    assert console_errors(browser) == []
    print(f"\npage load (navigation start to load event): without versions {first_load_s * 1000:.0f} ms, "
          f"with {len(browser.find_elements(By.CSS_SELECTOR, '[data-part=datasets] .row'))} datasets, "
          f"{len(browser.find_elements(By.CSS_SELECTOR, '.job'))} jobs, 2 versions {loaded_s * 1000:.0f} ms")
    screenshot(browser, figures / "page-desktop.png", DESKTOP, mobile=False)

    # At a phone's width: nothing wider than the screen, the buttons still there.
    screenshot(browser, figures / "page-phone.png", PHONE, mobile=True)
    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                            {"width": PHONE[0], "height": PHONE[1], "deviceScaleFactor": 1, "mobile": True})
    assert browser.execute_script("return document.documentElement.scrollWidth") <= PHONE[0]
    assert browser.find_element(By.CSS_SELECTOR, 'button[data-action="calibrate"]').is_displayed()
    browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
    assert console_errors(browser) == []


def captured_pairs_before_calibrating(browser, server) -> None:
    """The dataset's pairs as captured: the image and the cloud from above, pair by pair."""
    assert "No calibration with overlays yet" in text(browser, "#viewer-empty")
    click(browser, 'button[data-action="pairs"][data-dataset="field"]')
    until(browser, 10, lambda d: "dataset field as captured, pair 0" in text(d, "#viewer-title"))
    until(browser, 10, images_loaded)
    state = lens_state(browser)
    assert "/datasets/field/pairs/0/image" in state["after"]["src"]
    with server.client() as client:
        width = client.get("/datasets/field").json()["camera"]["width"]
    assert state["after"]["natural"] == width  # the captured image itself (no smaller than the lens shows it)
    assert "/datasets/field/pairs/0/cloud.png" in attr(browser, "#ov-cloud", "src")
    assert not browser.find_element(By.ID, "stage-toggle").is_displayed()  # nothing to compare before calibrating
    assert "source" in text(browser, "#pair-meta")  # the pair's meta.yaml
    click(browser, '#viewer-pairs button[data-pair="1"]')
    until(browser, 10, lambda d: "/pairs/1/image" in lens_state(d)["after"]["src"])
    until(browser, 10, images_loaded)


def first_calibration(browser, server) -> dict:
    """Calibrate from the page as it was left (no choice of start): the job's verdict shown in its colour."""
    click(browser, 'button[data-action="calibrate"][data-dataset="field"]')
    until(browser, 10, lambda d: d.find_elements(By.CSS_SELECTOR, '.job[data-kind="calibrate"]'))
    shown = watch(browser, '.job[data-kind="calibrate"]', lambda t: finished(browser, '.job[data-kind="calibrate"]'),
                  240)
    assert any("running" in s for s in shown), shown
    assert len(shown) >= 2, shown  # the stage moved on while it ran (edges, optimising, overlays)
    with server.client() as client:
        job = client.get("/jobs", params={"kind": "calibrate"}).json()[0]
        assert job["params"]["init"] in ("rig", "search") and job["status"] == "succeeded", job
        v1 = client.get("/extrinsics/versions/1").json()
    verdict = v1["verdict"]["status"]
    badge = browser.find_element(By.CSS_SELECTOR, '.job[data-kind="calibrate"] .badge')
    assert badge.text == f"verdict {verdict}" and verdict in badge.get_attribute("class").split()
    assert "succeeded" not in text(browser, '.job[data-kind="calibrate"]')
    until(browser, 10, lambda d: "version 1, verdict" in message(d)[0])
    assert message(browser)[0].startswith(f"Calibration of field: job {job['id']} done: version 1, verdict {verdict}")
    assert message(browser)[1] == TONE[verdict]
    until(browser, 10, lambda d: d.find_elements(By.ID, "v1"))
    return v1


def before_after_zoom_and_pan(browser, server, v1: dict) -> None:
    """The version's overlays: before and after at the same place, zoomed and panned together."""
    click(browser, '#v1 button[data-action="view"]')
    until(browser, 10, lambda d: "version 1, pair 0" in text(d, "#viewer-title"))
    until(browser, 10, lambda d: images_loaded(d, ("lens-before", "lens-after", "ov-closeup", "ov-cloud")))
    state = lens_state(browser)
    assert "stage=after" in state["after"]["src"] and not state["after"]["hidden"] and state["before"]["hidden"]
    assert state["after"]["natural"] == v1["quality"]["image_size_px"][0]  # the overlay at full resolution
    click(browser, "#viewer button[data-zoom=in]")
    click(browser, "#viewer button[data-zoom=in]")
    assert lens_state(browser)["zoom"] == pytest.approx(2.25, abs=1e-3)
    lens = browser.find_element(By.ID, "lens")
    ActionChains(browser).move_to_element(lens).click_and_hold().move_by_offset(-60, -25).release().perform()
    panned = lens_state(browser)
    assert translate(panned["after"]["transform"]) != translate(state["after"]["transform"])
    click(browser, '#stage-toggle button[data-stage="before"]')
    now = lens_state(browser)
    assert now["stage"] == "before" and not now["before"]["hidden"] and now["after"]["hidden"]
    assert "stage=before" in now["before"]["src"] and now["before"]["transform"] == panned["after"]["transform"]
    lens.send_keys("b")  # the key switches back, still at the same place
    assert lens_state(browser)["stage"] == "after" and lens_state(browser)["after"]["transform"] == now["before"][
        "transform"]
    ActionChains(browser).scroll_from_origin(ScrollOrigin.from_element(lens), 0, -300).perform()
    until(browser, 5, lambda d: lens_state(d)["zoom"] > 2.25)  # the wheel zooms in
    click(browser, "#viewer button[data-zoom=fit]")
    assert lens_state(browser)["zoom"] == 1 and translate(lens_state(browser)["after"]["transform"]) == (0, 0)
    assert f"{v1['quality']['image_size_px'][0]}×{v1['quality']['image_size_px'][1]} px" in lens_state(browser)["label"]


def activate_with_confirmation(browser, server, v1: dict) -> None:
    """An untrusted version asks first, with its reasons; keeping the active one changes nothing."""
    if v1["status"] == "active":  # a trusted first version is active at once: nothing to confirm
        assert v1["verdict"]["status"] == "trusted"
        return
    click(browser, '#v1 button[data-action="activate"]')
    until(browser, 5, lambda d: d.find_element(By.ID, "confirm").is_displayed())
    assert texts(browser, "#confirm-reasons li") == v1["verdict"]["reasons"]
    assert v1["verdict"]["status"] in text(browser, "#confirm-lead")
    click(browser, "#confirm-no")
    assert not browser.find_element(By.ID, "confirm").is_displayed()
    with server.client() as client:
        assert client.get("/extrinsics/versions/1").json()["status"] == "candidate"
    click(browser, '#v1 button[data-action="activate"]')
    click(browser, "#confirm-yes")
    until(browser, 10, lambda d: attr(d, "#v1", "data-status") == "active")
    # With an active version the next calibration starts from it (the operator did not choose otherwise).
    until(browser, 10, lambda d: d.find_element(By.ID, "init-select").get_attribute("value") == "active")


def advice_and_options(browser, server, v1: dict) -> None:
    """The advice's actions fill the page's options; a calibration sends them (then it is cancelled)."""
    steps = v1["verdict"].get("next_steps") or []
    assert bool(steps) == (v1["verdict"]["status"] != "trusted")
    if steps:
        assert texts(browser, "#v1 .next-steps li")[0].startswith(steps[0])
        # Fewer than 12 pairs: the advice asks for more, and its button prepares that capture.
        click(browser, '#v1 button[data-advice="capture"]')
        assert browser.find_element(By.NAME, "dataset").get_attribute("value") == "field"
    browser.execute_script("document.getElementById('calibrate-options').open = true")
    for name, value in (("prior-x", "0.1"), ("prior-y", "0.05"), ("prior-z", "-0.15"), ("prior-sigma-cm", "1.5"),
                        ("tolerance-deg", "0.3"), ("tolerance-cm", "2.5")):
        field = browser.find_element(By.NAME, name)
        field.clear()
        field.send_keys(value)
    browser.find_element(By.NAME, "fix-translation").click()
    click(browser, 'button[data-action="calibrate"][data-dataset="field"]')
    until(browser, 10, lambda d: len(d.find_elements(By.CSS_SELECTOR, '.job[data-kind="calibrate"]')) == 2)
    with server.client() as client:
        job = client.get("/jobs", params={"kind": "calibrate"}).json()[0]
    assert job["params"]["prior"] == {"xyz_m": [0.1, 0.05, -0.15], "sigma_cm": 1.5}
    assert job["params"]["fix_translation"] is True
    assert job["params"]["tolerance"] == {"rotation_deg": 0.3, "translation_cm": 2.5}
    options = "lever arm ± 1.5 cm, translation fixed, tolerance 0.3° / 2.5 cm"
    assert options in text(browser, f'[data-job="{job["id"]}"]')
    click(browser, f'button[data-action="cancel"][data-job="{job["id"]}"]')
    until(browser, 30, lambda d: f"job {job['id']} cancelled" in message(d)[0])
    # An out-of-range value is refused by the browser before any request.
    field = browser.find_element(By.NAME, "tolerance-deg")
    field.clear()
    field.send_keys("50")
    click(browser, 'button[data-action="calibrate"][data-dataset="field"]')
    time.sleep(1)
    with server.client() as client:
        assert len(client.get("/jobs", params={"kind": "calibrate"}).json()) == 2
    for name in ("prior-x", "prior-y", "prior-z", "prior-sigma-cm", "tolerance-deg", "tolerance-cm"):
        browser.find_element(By.NAME, name).clear()
    browser.find_element(By.NAME, "fix-translation").click()


def manual_version_and_change(browser, server) -> None:
    """A second version 3 cm along x and 0.5 deg in yaw off the first: its change per axis, and activating a
    version without a verdict asks first."""
    with server.client() as client:
        v1 = client.get("/extrinsics/versions/1").json()
        rpy = np.asarray(v1["T_camera_lidar"]["rpy_deg"]) + [0.0, 0.0, 0.5]
        xyz = np.asarray(v1["T_camera_lidar"]["xyz_m"]) + [0.03, 0.0, 0.0]
        response = client.post("/extrinsics/versions", json={"T_camera_lidar": {"rpy_deg": rpy.tolist(),
                                                                                "xyz_m": xyz.tolist()},
                                                             "note": "from the total station"})
        assert response.status_code == 201 and response.json()["status"] == "candidate"
    until(browser, 10, lambda d: d.find_elements(By.ID, "v2"))
    change = [float(t) for t in texts(browser, "#v2 tr.change td")]
    assert change[3:] == [3.0, 0.0, 0.0]  # cm, exactly the lever arm's change
    assert np.linalg.norm(change[:3]) == pytest.approx(0.5, abs=0.015)  # deg, the rotation between them
    click(browser, '#v2 button[data-action="activate"]')
    until(browser, 5, lambda d: d.find_element(By.ID, "confirm").is_displayed())
    assert "no verdict" in text(browser, "#confirm-lead")
    assert "from the total station" in text(browser, "#confirm-reasons")
    click(browser, "#confirm-yes")
    until(browser, 10, lambda d: attr(d, "#v2", "data-status") == "active")
    assert attr(browser, "#v1", "data-status") == "superseded"
    assert "version 2" in text(browser, '[data-part="summary"]')
    assert message(browser) == ("Version 2 is active.", "ok")


def check_with_every_reason(browser, server) -> None:
    """A check of the active version (2, 3 cm and 0.5 deg off the calibration): its status and all its reasons."""
    click(browser, 'button[data-action="check"][data-dataset="field"]')
    until(browser, 10, lambda d: d.find_elements(By.CSS_SELECTOR, '.job[data-kind="check"]'))
    watch(browser, '.job[data-kind="check"]', lambda t: finished(browser, '.job[data-kind="check"]'), 180)
    with server.client() as client:
        check = client.get("/jobs", params={"kind": "check"}).json()[0]
    status = check["result"]["status"]
    assert check["status"] == "succeeded" and len(check["result"]["reasons"]) >= 1
    row = f'.job[data-job="{check["id"]}"]'
    assert texts(browser, row + " .reasons li") == check["result"]["reasons"]
    groups = check["result"]["groups"]  # each judged group's length against its bound (none here: few places)
    lengths = texts(browser, row + " .lengths li")
    assert len(lengths) == len(groups)
    for line, (name, g) in zip(lengths, sorted(groups.items()), strict=True):
        assert line.startswith(f"{name}: {g['length']:.3g} ") and f"at most {g['upper']:.3g}" in line
    assert text(browser, row + " .badge") == status
    until(browser, 10, lambda d: f"job {check['id']} done: {status}" in message(d)[0])
    assert message(browser)[1] == TONE[status]


# -- many versions, live updates, an unreachable service --------------------------------------------------------
def live_sizes(driver) -> list[int]:
    """Body sizes (bytes) of the /ui/live answers since the page was opened."""
    return driver.execute_script("return performance.getEntriesByType('resource')"
                                 ".filter(e => e.name.includes('/ui/live')).map(e => e.decodedBodySize);")


def test_versions_paged_live_diffs_and_unreachable_banner(browser, tmp_path):
    """25 versions: the newest 10 on the page, 10 more per click; /ui/live sends only parts that changed; the
    banner while the service does not answer, gone when it does again; HEAD / answers."""
    server = Server(tmp_path / "data").start()
    try:
        with server.client() as client:
            for k in range(25):
                body = {"T_camera_lidar": {"rpy_deg": [0.0, 15.0, -55.0 + 0.01 * k], "xyz_m": [0.1, 0.05, -0.15]}}
                assert client.post("/extrinsics/versions", json=body).status_code == 201
            head = client.head("/")
            assert head.status_code == 200 and head.headers["content-type"].startswith("text/html")
        browser.get("about:blank")
        console_errors(browser)  # drained: an earlier test's page may have polled its stopped service
        load(browser, server.url + "/")
        numbers = lambda d: [int(v) for v in d.execute_script(  # noqa: E731
            "return [...document.querySelectorAll('.version')].map(v => v.dataset.version)")]
        assert numbers(browser) == list(range(25, 15, -1))  # the newest 10, newest first
        assert "the newest 10 of 25" in text(browser, "#versions-more")
        click(browser, 'button[data-action="more-versions"]')
        until(browser, 10, lambda d: len(numbers(d)) == 20)
        click(browser, 'button[data-action="more-versions"]')
        until(browser, 10, lambda d: numbers(d) == list(range(25, 0, -1)))
        assert not browser.find_elements(By.CSS_SELECTOR, 'button[data-action="more-versions"]')

        # Nothing changed: a live answer carries no part (a few hundred bytes, not the page).
        with server.client() as client:
            hashes = client.get("/ui/live", params={"shown": 25}).json()["hashes"]
            have = ",".join(f"{name}:{value}" for name, value in hashes.items())
            again = client.get("/ui/live", params={"shown": 25, "have": have}).json()
        assert again["parts"] == {} and again["hashes"] == hashes
        time.sleep(9)  # two of the page's own polls
        assert min(live_sizes(browser)[-2:]) < 600, live_sizes(browser)
        with server.client() as client:
            client.post("/extrinsics/versions", json={"T_camera_lidar": {"rpy_deg": [0, 15, -54], "xyz_m": [0, 0, 0]}})
        until(browser, 10, lambda d: numbers(d)[:2] == [26, 25])
        assert len(numbers(browser)) == 26  # all still shown: the page asks for as many as it shows
        assert console_errors(browser) == []

        # The service stops answering (SIGSTOP: connections hang), then answers again.
        server.proc.send_signal(signal.SIGSTOP)
        try:
            until(browser, 30, lambda d: d.find_element(By.ID, "offline").is_displayed())
            assert "does not answer" in text(browser, "#offline")
            assert "offline" in browser.find_element(By.TAG_NAME, "body").get_attribute("class")
        finally:
            server.proc.send_signal(signal.SIGCONT)
        until(browser, 30, lambda d: not d.find_element(By.ID, "offline").is_displayed())
        assert message(browser) == ("The service answers again.", "ok")
        assert console_errors(browser, allowed=("/ui/live",)) == []
    finally:
        browser.get("about:blank")
        server.stop()


def big_pair(data: Path, width: int = 2048) -> str:
    """A one-pair dataset whose image is ``width`` px wide (a small simulated pair's image, enlarged)."""
    root = simulated_dataset(data, "wide", pairs=1)
    image_path = root / "pairs" / "0000" / "image.png"
    image = cv2.imread(str(image_path))
    cv2.imwrite(str(image_path), cv2.resize(image, (width, width // 2), interpolation=cv2.INTER_NEAREST))
    rig = yaml.safe_load((root / "rig.yaml").read_text())
    rig["camera"].update(width=width, height=width // 2)
    (root / "rig.yaml").write_text(yaml.safe_dump(rig))
    return root.name


def test_zoom_loads_full_resolution_and_pans(browser, tmp_path):
    """A 2048-px image: the lens loads a copy as wide as it first, the file itself once zoomed past that copy;
    1:1 shows one image pixel per screen pixel; a drag pans, within the image."""
    name = big_pair(tmp_path / "data")
    server = Server(tmp_path / "data").start()
    try:
        browser.get("about:blank")
        console_errors(browser)
        load(browser, server.url + "/")
        click(browser, f'button[data-action="pairs"][data-dataset="{name}"]')
        # Loaded means decoded: an image element is "complete" before its new source has arrived.
        until(browser, 10, lambda d: images_loaded(d, ("lens-after",)) and lens_state(d)["after"]["src"]
              and lens_state(d)["after"]["natural"] > 0)
        first = lens_state(browser)
        lens_width = browser.execute_script("return document.getElementById('lens').clientWidth")
        assert "width=" in first["after"]["src"] and first["full"] == "false"
        assert lens_width <= first["after"]["natural"] < 2048  # a copy for the screen, not the file
        click(browser, "#viewer button[data-zoom=in]")
        until(browser, 10, lambda d: lens_state(d)["full"] == "true")
        until(browser, 10, lambda d: lens_state(d)["after"]["natural"] == 2048)
        assert "width=" not in lens_state(browser)["after"]["src"]
        click(browser, "#viewer button[data-zoom=full]")
        until(browser, 10, lambda d: lens_state(d)["zoom"] == pytest.approx(2048 / lens_width, abs=1e-3))
        assert "100 % of full resolution (2048×1024 px)" in lens_state(browser)["label"]
        lens = browser.find_element(By.ID, "lens")
        x0, y0 = translate(lens_state(browser)["after"]["transform"])
        ActionChains(browser).move_to_element(lens).click_and_hold().move_by_offset(100, 40).release().perform()
        x1, y1 = translate(lens_state(browser)["after"]["transform"])
        assert (x1 - x0, y1 - y0) == pytest.approx((min(100, -x0), min(40, -y0)), abs=1.5)  # clamped at the edge
        for _ in range(12):  # far past the top left corner: the image's corner stays at the lens's
            ActionChains(browser).move_to_element(lens).click_and_hold().move_by_offset(150, 60).release().perform()
        assert translate(lens_state(browser)["after"]["transform"]) == (0, 0)
        assert console_errors(browser) == []
    finally:
        browser.get("about:blank")
        server.stop()


# -- the token, a head ------------------------------------------------------------------------------------------
def test_page_asks_for_the_token_and_sends_it(browser, tmp_path):
    server = Server(tmp_path / "data", env={"RIGD_TOKEN": TOKEN}).start()
    try:
        load(browser, server.url + "/")
        browser.execute_script("sessionStorage.clear()")
        load(browser, server.url + "/")
        assert TOKEN not in browser.page_source
        assert browser.find_element(By.ID, "token-form").is_displayed()

        # Without a token nothing is sent: the page asks for it.
        click(browser, "#capture-form button[type=submit]")
        assert "needs its API token" in text(browser, "#message")
        with server.client() as client:
            assert client.get("/jobs").json() == []

        # A wrong token is refused by the service (401) and forgotten; the right one starts the capture.
        browser.find_element(By.ID, "token-input").send_keys("wrong-token-of-some-length")
        click(browser, "#token-form button[type=submit]")
        click(browser, "#capture-form button[type=submit]")
        until(browser, 10, lambda d: "token was refused" in text(d, "#message"))
        assert browser.execute_script("return sessionStorage.getItem('rigd-token')") is None
        assert browser.find_element(By.ID, "token-form").is_displayed()
        browser.find_element(By.ID, "token-input").send_keys(TOKEN)
        click(browser, "#token-form button[type=submit]")
        click(browser, "#capture-form button[type=submit]")
        until(browser, 10, lambda d: d.find_elements(By.CSS_SELECTOR, '.job[data-kind="capture"]'))
        assert browser.find_element(By.ID, "token-set").is_displayed()

        # The page (and its live parts) never carry the token; the capture is cancelled from its button.
        assert TOKEN not in browser.page_source
        with server.client() as client:
            assert TOKEN not in client.get("/").text and TOKEN not in client.get("/ui/live").text
            job = client.get("/jobs").json()[0]
        click(browser, f'button[data-action="cancel"][data-job="{job["id"]}"]')
        with server.client() as client:
            assert wait_job(client, job["id"], 60)["status"] in ("cancelled", "succeeded")
        assert console_errors(browser, allowed=("401 (Unauthorized)",)) == []
    finally:
        browser.execute_script("sessionStorage.clear()")
        browser.get("about:blank")
        server.stop()


def lens_and_figure_srcs(driver) -> dict[str, str]:
    return driver.execute_script(
        "const out = {}; for (const id of ['lens-before', 'lens-after', 'ov-closeup', 'ov-cloud'])"
        " out[id] = document.getElementById(id).getAttribute('src') || ''; return out;")


def test_page_picks_the_sensor_of_a_head(browser, tmp_path, figures):
    """A multi-camera head's version: a sensor picker beside the pair's overlays (the report's sensors, the
    first chosen), switching before, after and the close-up to that sensor's files; the cloud stays per pair.
    Its captured pairs show each sensor's image too."""
    data = tmp_path / "data"
    dataset = write_simulated_dataset(data / "datasets" / "head", "outdoor", 2, 5, width=160, height=200,
                                      progress=False, head=True)
    server = Server(data).start()
    try:
        with server.client() as client:
            response = client.post("/calibrate", json={"dataset": "head", "init": perturbed_truth(dataset)})
            assert response.status_code == 202, response.text
            assert wait_job(client, response.json()["id"], 240)["status"] == "succeeded"
            page = client.get("/").text
        sensors = [f"cam{k}" for k in range(5)]
        assert f'data-sensors="{",".join(sensors)}"' in page  # from the version's report, rendered by the server

        browser.get("about:blank")
        console_errors(browser)  # drained: an earlier test's page may have polled its stopped service
        load(browser, server.url + "/")
        until(browser, 10, images_loaded)  # the newest calibration, shown without a click
        picker = "#viewer-sensors button[data-action=sensor]"
        assert browser.find_element(By.ID, "viewer-sensors").is_displayed()
        assert texts(browser, picker) == sensors
        assert texts(browser, picker + ".current") == ["cam0"]  # the first sensor by default
        first = lens_and_figure_srcs(browser)
        assert all("&sensor=cam0" in first[s] for s in ("lens-before", "lens-after", "ov-closeup")), first
        assert "sensor=" not in first["ov-cloud"]

        click(browser, picker + '[data-sensor="cam1"]')
        until(browser, 10, lambda d: "&sensor=cam1" in lens_and_figure_srcs(d)["lens-after"])
        until(browser, 10, images_loaded)  # the files exist: 0000_cam1_*.png
        now = lens_and_figure_srcs(browser)
        assert all("&sensor=cam1" in now[s] for s in ("lens-before", "lens-after", "ov-closeup")), now
        assert now["ov-cloud"] == first["ov-cloud"]
        assert texts(browser, picker + ".current") == ["cam1"]
        assert "version 1, pair 0, cam1" in text(browser, "#viewer-title")

        # The choice survives a change of pair and the page's refresh of its parts.
        click(browser, '#viewer-pairs button[data-pair="1"]')
        until(browser, 10, lambda d: "/overlays/1.png" in lens_and_figure_srcs(d)["lens-after"])
        assert "&sensor=cam1" in lens_and_figure_srcs(browser)["lens-after"]
        until(browser, 10, images_loaded)
        assert console_errors(browser) == []
        viewer = browser.find_element(By.ID, "viewer")
        full = browser.execute_script("return document.documentElement.scrollHeight")
        browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",  # the whole card in the viewport
                                {"width": DESKTOP[0], "height": full, "deviceScaleFactor": 1, "mobile": False})
        time.sleep(0.5)
        until(browser, 10, images_loaded)
        viewer.screenshot(str(figures / "page-head-sensors.png"))
        browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})

        heads_captured_images(browser, sensors)
        assert console_errors(browser) == []
    finally:
        browser.get("about:blank")  # no page left polling the service stopped next
        server.stop()


def heads_captured_images(browser, sensors: list[str]) -> None:
    """A head's captured pairs: each sensor's image as captured."""
    picker = "#viewer-sensors button[data-action=sensor]"
    click(browser, 'button[data-action="pairs"][data-dataset="head"]')
    until(browser, 10, lambda d: "dataset head as captured" in text(d, "#viewer-title"))
    assert texts(browser, picker) == sensors
    click(browser, picker + '[data-sensor="cam3"]')
    until(browser, 10, lambda d: "/datasets/head/pairs/0/image?sensor=cam3" in lens_state(d)["after"]["src"])
    until(browser, 10, images_loaded)
    assert lens_state(browser)["after"]["natural"] == 160


# -- without a browser ------------------------------------------------------------------------------------------
def test_only_a_heads_report_lists_sensors():
    """One camera's (or a manual) version has no sensors to pick; a head's are its report's, in order."""
    from rigd.web.views import report_sensors

    assert report_sensors({"pairs": [{"edge_pixels": 10, "edge_points": 5}]}) == []
    assert report_sensors({}) == []
    head = {"pairs": [{"edge_pixels": 3, "edge_pixels_per_sensor": {"cam0": 1, "cam1": 2}}]}
    assert report_sensors(head) == ["cam0", "cam1"]


def test_the_advice_the_page_acts_on_is_the_advice_written():
    """Each advice button is keyed to words of rigd/calibration/advice.py: rewording the advice must not leave
    a button that never shows."""
    import rigd.calibration.advice as advice
    from rigd.web.views import ADVICE_ACTIONS, advice_actions

    source = inspect.getsource(advice)
    assert [words for words, _, _ in ADVICE_ACTIONS if words not in source] == []
    step = "only 2 pairs: rigd is measured with 12 (rigd capture --n 12)"
    assert advice_actions(step) == [("capture", "Capture more pairs")]
    assert advice_actions("x: ... give the lever arm (rig.yaml prior: {...}, or --fix translation)") == [
        ("prior", "Give the lever arm"), ("fix", "Fix the translation")]


def test_live_reads_only_known_parts():
    from rigd.web.routes import known_hashes

    assert known_hashes("jobs:ab12,versions:cd34,bogus:1,,summary") == {"jobs": "ab12", "versions": "cd34",
                                                                        "summary": ""}
