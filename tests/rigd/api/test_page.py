"""The operator page (GET /) in a real headless Chromium (Debian's ``chromium`` and ``chromium-driver``, driven by
Selenium) against a real ``rigd serve``: no console errors, a simulated capture and a calibration started
from its buttons and seen progressing on it, a check, a version activated, the token asked for and sent
when the service has one, and the layout at a phone's width. Without the two packages the tests are skipped,
reason printed (``apt-get install chromium chromium-driver``); with ``RIGD_REQUIRE_BROWSER=1`` (.ci/run) they fail.

Screenshots go to the test's tmp dir, or to ``RIGD_PAGE_FIGURES`` (docs/figures/ holds a set made so).
The page's load time (navigation start to the load event) is printed: ``pytest -s tests/rigd/api/test_page.py``.
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

import numpy as np
import pytest
from api_helpers import Server, perturbed_truth, wait_job
from selenium import webdriver
from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.chrome.service import Service as DriverService
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select, WebDriverWait

from rigd.simulate import write_simulated_dataset

# Debian's packages (.ci/run installs them): browser and driver come from one source package, so they match.
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
INSTALL_BROWSER = "sudo apt-get install chromium chromium-driver"
REQUIRE_BROWSER = "RIGD_REQUIRE_BROWSER"
TOKEN = "correct-horse-battery-staple"
DESKTOP = (1280, 900)
PHONE = (360, 740)


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


def click(driver, css: str) -> None:
    until(driver, 10, lambda d: d.find_element(By.CSS_SELECTOR, css).is_enabled())
    for _ in range(5):  # the element may be replaced by a refresh between finding and clicking it
        try:
            driver.find_element(By.CSS_SELECTOR, css).click()
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
    time.sleep(0.3)
    driver.save_screenshot(str(path))
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": mobile})


def images_loaded(driver) -> bool:
    return driver.execute_script(
        "return ['ov-before', 'ov-after', 'ov-closeup', 'ov-cloud'].every(id => {"
        " const i = document.getElementById(id);"
        " return !i.hidden && i.complete && i.naturalWidth > 0; })")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    server = Server(tmp_path_factory.mktemp("page") / "data").start()
    yield server
    server.stop()


def test_page_capture_calibrate_check_activate(browser, server, figures):
    first_load_s = load(browser, server.url + "/")
    assert browser.title == "rigd"
    assert console_errors(browser) == []
    assert "No datasets yet" in text(browser, '[data-part="datasets"]')
    assert text(browser, '[data-part="sensors"]').startswith("LiDAR")

    # A capture of 2 pairs from the simulated rig (the rig file's sources), seen progressing.
    browser.find_element(By.NAME, "dataset").send_keys("field")
    click(browser, "#capture-form button[type=submit]")
    finished = lambda t: "succeeded" in t or "failed" in t  # noqa: E731
    receiving = re.compile(r"[1-9][0-9]* packets/s")
    shown = watch(browser, "#capture-job", lambda t: bool(receiving.search(t)) or finished(t), 120)
    assert "running" in shown[-1] and receiving.search(shown[-1]) and "still for" in shown[-1], shown  # live
    browser.save_screenshot(str(figures / "page-capturing.png"))
    shown += watch(browser, "#capture-job", finished, 120)
    assert "succeeded" in shown[-1], shown
    assert any("running" in s and "pairs" in s for s in shown), shown  # its state and pair count, live
    assert "2 pairs written" in shown[-1]
    until(browser, 10, lambda d: "field" in text(d, '[data-part="datasets"]'))
    assert "2 pairs" in text(browser, '[data-dataset="field"]')

    # A calibration from the rig file's guess (there is no active version yet), seen progressing.
    Select(browser.find_element(By.ID, "init-select")).select_by_value("rig")
    click(browser, 'button[data-action="calibrate"][data-dataset="field"]')
    until(browser, 10, lambda d: d.find_elements(By.CSS_SELECTOR, '.job[data-kind="calibrate"]'))
    shown = watch(browser, '.job[data-kind="calibrate"]', finished, 240)
    assert "succeeded" in shown[-1] and "version 1" in shown[-1], shown
    assert any("running" in s for s in shown), shown
    assert len(shown) >= 2, shown  # the stage moved on while it ran (edges, optimising, overlays)
    until(browser, 10, lambda d: d.find_elements(By.ID, "v1"))

    # The overlays of the new version: before, after and the close-up, all loaded.
    until(browser, 10, images_loaded)
    assert "version 1, pair 0" in text(browser, "#overlay-title")
    assert browser.find_element(By.ID, "ov-closeup-link").get_attribute("href").endswith("stage=closeup")
    assert not browser.find_element(By.ID, "overlay-sensors").is_displayed()  # one camera: no sensor to pick

    with server.client() as client:
        v1 = client.get("/extrinsics/versions/1").json()
        steps = v1["verdict"].get("next_steps") or []  # what to do about an untrusted result, shown under it
        assert bool(steps) == (v1["verdict"]["status"] != "trusted")
        if steps:
            assert steps[0] in text(browser, "#v1 .next-steps")
        if v1["status"] != "active":  # an untrusted first version waits for a person: that is this page
            click(browser, '#v1 button[data-action="activate"]')
            until(browser, 10, lambda d: d.find_element(By.ID, "v1").get_attribute("data-status")
                                             == "active")
        # A second version 3 cm along x and 0.5 deg in yaw from the first (stored through the API).
        rpy = np.asarray(v1["T_camera_lidar"]["rpy_deg"]) + [0.0, 0.0, 0.5]
        xyz = np.asarray(v1["T_camera_lidar"]["xyz_m"]) + [0.03, 0.0, 0.0]
        response = client.post("/extrinsics/versions", json={"T_camera_lidar": {"rpy_deg": rpy.tolist(),
                                                                                "xyz_m": xyz.tolist()}})
        assert response.status_code == 201 and response.json()["status"] == "candidate"

    # The page shows its change against the active version per axis, then activates it.
    until(browser, 10, lambda d: d.find_elements(By.ID, "v2"))
    change = [float(t) for t in texts(browser, "#v2 tr.change td")]
    assert change[3:] == [3.0, 0.0, 0.0]  # cm, exactly the lever arm's change
    assert np.linalg.norm(change[:3]) == pytest.approx(0.5, abs=0.015)  # deg, the rotation between them
    click(browser, '#v2 button[data-action="activate"]')
    until(browser, 10, lambda d: d.find_element(By.ID, "v2").get_attribute("data-status") == "active")
    assert browser.find_element(By.ID, "v1").get_attribute("data-status") == "superseded"
    assert "version 2" in text(browser, '[data-part="summary"]')
    assert "Version 2 is active" in text(browser, "#message")

    # A check of the active version (2, 3 cm and 0.5 deg off the calibration) against the dataset.
    click(browser, 'button[data-action="check"][data-dataset="field"]')
    until(browser, 10, lambda d: d.find_elements(By.CSS_SELECTOR, '.job[data-kind="check"]'))
    shown = watch(browser, '.job[data-kind="check"]', finished, 180)
    assert "succeeded" in shown[-1] and any(v in shown[-1] for v in ("ok", "drifted", "unknown")), shown
    with server.client() as client:
        check = client.get("/jobs", params={"kind": "check"}).json()[0]
    assert f"→ {check['result']['status']}" in shown[-1]  # the job's own verdict, as the API has it

    assert console_errors(browser) == []
    loaded_s = load(browser, server.url + "/")  # with datasets, jobs and versions to render
    until(browser, 10, images_loaded)
    assert console_errors(browser) == []
    print(f"\npage load (navigation start to load event): empty {first_load_s * 1000:.0f} ms, "
          f"with 1 dataset, {len(browser.find_elements(By.CSS_SELECTOR, '.job'))} jobs, 2 versions "
          f"{loaded_s * 1000:.0f} ms")
    screenshot(browser, figures / "page-desktop.png", DESKTOP, mobile=False)

    # At a phone's width: nothing wider than the screen, the buttons still there.
    screenshot(browser, figures / "page-phone.png", PHONE, mobile=True)
    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                            {"width": PHONE[0], "height": PHONE[1], "deviceScaleFactor": 1, "mobile": True})
    assert browser.execute_script("return document.documentElement.scrollWidth") <= PHONE[0]
    assert browser.find_element(By.CSS_SELECTOR, 'button[data-action="calibrate"]').is_displayed()
    browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
    assert console_errors(browser) == []


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
        server.stop()


def overlay_srcs(driver) -> dict[str, str]:
    return driver.execute_script(
        "const out = {}; for (const s of ['before', 'after', 'closeup', 'cloud'])"
        " out[s] = document.getElementById('ov-' + s).getAttribute('src') || ''; return out;")


def test_page_picks_the_sensor_of_a_head(browser, tmp_path, figures):
    """A multi-camera head's version: a sensor picker beside the pair's overlays (the report's sensors, the
    first chosen), switching before, after and the close-up to that sensor's files; the cloud stays per pair."""
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
        until(browser, 10, images_loaded)
        picker = "#overlay-sensors button[data-action=sensor]"
        assert browser.find_element(By.ID, "overlay-sensors").is_displayed()
        assert texts(browser, picker) == sensors
        assert texts(browser, picker + ".current") == ["cam0"]  # the first sensor by default
        first = overlay_srcs(browser)
        assert all("&sensor=cam0" in first[s] for s in ("before", "after", "closeup")), first
        assert "sensor=" not in first["cloud"]

        click(browser, picker + '[data-sensor="cam1"]')
        until(browser, 10, lambda d: "&sensor=cam1" in overlay_srcs(d)["after"])
        until(browser, 10, images_loaded)  # the files exist: 0000_cam1_*.png
        now = overlay_srcs(browser)
        assert all("&sensor=cam1" in now[s] for s in ("before", "after", "closeup")), now
        assert now["cloud"] == first["cloud"]
        assert texts(browser, picker + ".current") == ["cam1"]
        assert "version 1, pair 0, cam1" in text(browser, "#overlay-title")
        assert browser.find_element(By.ID, "ov-after-link").get_attribute("href").endswith("stage=after&sensor=cam1")

        # The choice survives a change of pair and the page's refresh of its parts.
        click(browser, '#overlay-pairs button[data-pair="1"]')
        until(browser, 10, lambda d: "/overlays/1.png" in overlay_srcs(d)["after"])
        assert "&sensor=cam1" in overlay_srcs(browser)["after"]
        until(browser, 10, images_loaded)
        assert console_errors(browser) == []
        overlays = browser.find_element(By.ID, "overlays")
        full = browser.execute_script("return document.documentElement.scrollHeight")
        browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",  # the whole card in the viewport
                                {"width": DESKTOP[0], "height": full, "deviceScaleFactor": 1, "mobile": False})
        time.sleep(0.5)
        until(browser, 10, images_loaded)
        overlays.screenshot(str(figures / "page-head-sensors.png"))
        browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
    finally:
        browser.get("about:blank")  # no page left polling the service stopped next
        server.stop()


def test_only_a_heads_report_lists_sensors():
    """One camera's (or a manual) version has no sensors to pick; a head's are its report's, in order."""
    from rigd.api.routes.page import report_sensors

    assert report_sensors({"pairs": [{"edge_pixels": 10, "edge_points": 5}]}) == []
    assert report_sensors({}) == []
    head = {"pairs": [{"edge_pixels": 3, "edge_pixels_per_sensor": {"cam0": 1, "cam1": 2}}]}
    assert report_sensors(head) == ["cam0", "cam1"]
