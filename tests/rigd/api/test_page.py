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

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from api_helpers import Server, perturbed_truth, simulated_dataset, wait_job, wait_running
from selenium import webdriver
from selenium.common.exceptions import ElementClickInterceptedException, StaleElementReferenceException
from selenium.webdriver.chrome.service import Service as DriverService
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.actions.wheel_input import ScrollOrigin
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from rigd.capture import CaptureState
from rigd.web.words import page_words

# Debian's packages (.ci/run installs them): browser and driver come from one source package, so they match.
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
INSTALL_BROWSER = "sudo apt-get install chromium chromium-driver"
REQUIRE_BROWSER = "RIGD_REQUIRE_BROWSER"
TOKEN = "correct-horse-battery-staple"
DESKTOP = (1366, 900)
PHONE = (390, 844)
# Test clocks (fast_timers): the page's timers run this many times faster. How much depends on what a request
# given up on too soon (a slow answer taken for an offline service) would do: PAGE_CLOCK where it would replace
# the message the test reads (a request still has 4 s; a loaded machine's slowest answer seen took 0.3 s);
# BANNER_CLOCK where the banner is what is tested (2 s: it must come from the stopped service, not a slow
# answer); POLL_CLOCK where it changes nothing asserted (1 s; polls every 0.5 s).
PAGE_CLOCK = 2
BANNER_CLOCK = 4
POLL_CLOCK = 8
WIDE = "wide"  # a dataset whose one image is 2048 px wide (big_pair)
TONE = {"trusted": "ok", "ok": "ok", "weak": "warn", "unknown": "warn", "failed": "bad", "drifted": "bad"}


def missing_browser() -> list[str]:
    return [str(p) for p in (CHROMIUM, CHROMEDRIVER) if not p.exists()]


@pytest.fixture(scope="module")
def browser():
    if missing := missing_browser():
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
    """Wait for ``condition(driver)``; elements the page replaced meanwhile are looked up again. Polled every
    0.05 s (WebDriverWait's 0.5 s default cost up to half a second per wait, and this module waits often)."""
    return WebDriverWait(driver, timeout_s, poll_frequency=0.05,
                         ignored_exceptions=(StaleElementReferenceException,)).until(condition)


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
    # Between finding and clicking it, the element may be replaced by a refresh, or moved by an image that came in
    # (another element would get the click): then again.
    for _ in range(5):
        try:
            element = driver.find_element(By.CSS_SELECTOR, css)
            driver.execute_script("arguments[0].scrollIntoView({block: 'center'})", element)
            element.click()
            return
        except (StaleElementReferenceException, ElementClickInterceptedException) as error:
            missed = error
    raise AssertionError(f"could not click {css}") from missed


def watch(driver, css: str, done, timeout_s: float) -> list[str]:
    """The distinct texts ``css`` showed until ``done(text)`` (polled every 0.2 s)."""
    seen: list[str] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        now = text(driver, css)
        if now and (not seen or seen[-1] != now):
            seen.append(now)
        if now and done(now):
            if (last := text(driver, css)) and last != seen[-1]:  # done() may have read a part swapped later
                seen.append(last)
            return seen
        time.sleep(0.2)
    raise AssertionError(f"{css} did not finish in {timeout_s} s; it showed {seen}")


def finished(driver, css: str) -> bool:
    return attr(driver, css, "data-status") in ("succeeded", "failed", "cancelled")


def viewport(driver, width: int, height: int, mobile: bool = False) -> None:
    """Emulate a ``width`` x ``height`` viewport (CSS px) and wait until the page has it and its images are
    loaded (the lens takes its image's shape on load): what a fixed pause after the resize stood for."""
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": mobile})
    until(driver, 10, lambda d: d.execute_script("return [window.innerWidth, window.innerHeight]") == [width, height]
          and images_loaded(d))


def screenshot(driver, path: Path, size: tuple[int, int], mobile: bool) -> None:
    """The whole page at viewport ``size`` (CSS px), emulated as a phone when ``mobile``."""
    width, height = size
    viewport(driver, width, height, mobile)
    driver.execute_script("window.scrollTo(0, 0)")
    full = driver.execute_script("return document.documentElement.scrollHeight")  # laid out for the new size
    viewport(driver, width, full, mobile)
    driver.save_screenshot(str(path))
    viewport(driver, width, height, mobile)


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


def drag(driver, element, dx: int, dy: int) -> None:
    """Press on ``element``'s centre, move by (dx, dy) CSS px, release: one pointermove (Selenium's default
    interpolates each move over 250 ms, which a drag the page follows in absolute terms does not need)."""
    (ActionChains(driver, duration=0).move_to_element(element).click_and_hold().move_by_offset(dx, dy).release()
     .perform())


def message(driver) -> tuple[str, str]:
    """The top message's text and tone (its class: ok, warn, bad, or empty)."""
    return text(driver, "#message"), attr(driver, "#message", "class") or ""


@contextmanager
def fast_timers(driver, factor: float) -> Iterator[None]:
    """Pages opened meanwhile run their setTimeout delays ``factor`` times faster: a test clock, as freezegun is
    for Python. page.js times all it waits for with setTimeout (polls every 4 s, 1 s while a job runs, 3 s while
    offline; REQUEST_TIMEOUT_MS before a request counts as unanswered), so the page, unchanged, does the same
    things in the same order, sooner, and what is asserted about its polls, the banner and its recovery means
    what it did at the real pace. Chosen over Chromium's virtual time (Emulation.setVirtualTimePolicy), whose
    clock its policy pauses or runs ahead around the page's requests, where the banner is about a real request
    left unanswered; and over a pace setting in page.js, product code only tests would use. Pages opened once
    the script is removed run at the real pace."""
    script = driver.execute_cdp_cmd("Page.addScriptToEvaluateOnNewDocument", {"source": (
        "(() => { const setTimeout = window.setTimeout;"
        f" window.setTimeout = (f, ms, ...args) => setTimeout(f, (Number(ms) || 0) / {factor}, ...args); }})();")})
    try:
        yield
    finally:
        driver.execute_cdp_cmd("Page.removeScriptToEvaluateOnNewDocument", {"identifier": script["identifier"]})


# -- the services, made ahead ----------------------------------------------------------------------------------
# A service takes ~2 s to start and the head's ~6 s more to simulate and calibrate, none of it in the browser,
# while a test waiting for the page leaves a core idle; made by each test, that time came one test after
# another. So the services are made in two threads from the module's start, and a test waits (Future.result)
# only for what is not ready yet. The tests that need no more than a service come first; the loop last, when
# nothing is made any more: its capture runs in real time (a busy machine drops its LiDAR's turns) and its
# calibrations are the heaviest work here.
def start_fresh(root: Path) -> Server:
    return Server(root / "data").start()


def start_wide(root: Path) -> Server:
    big_pair(root / "data", WIDE)
    return Server(root / "data").start()


def start_token(root: Path) -> Server:
    return Server(root / "data", env={"RIGD_TOKEN": TOKEN}).start()


def start_head(root: Path) -> Server:
    """A head's dataset, "head" (2 pairs, five 160x200 sensors), and its calibration, version 1. Simulated by
    rigd simulate, a process of its own: in a thread here it would hold this process's GIL for seconds. Its
    service starts after it, so as not to slow the start of the one the first test waits for."""
    data = root / "data"
    dataset = data / "datasets" / "head"
    simulate = subprocess.run([sys.executable, "-m", "rigd", "simulate", str(dataset), "--scene", "outdoor",
                               "--pairs", "2", "--seed", "5", "--width", "160", "--height", "200", "--camera", "head"],
                              capture_output=True, text=True, timeout=120)
    assert simulate.returncode == 0, simulate.stderr
    server = Server(data).start()
    try:
        with server.client() as client:
            response = client.post("/calibrate", json={"dataset": "head", "init": perturbed_truth(dataset)})
            assert response.status_code == 202, response.text
            assert wait_job(client, response.json()["id"], 240)["status"] == "succeeded"
    except BaseException:
        server.stop()
        raise
    return server


def start_field(root: Path) -> Server:
    simulated_dataset(root / "data", "field")
    return Server(root / "data").start()


# The fixture, and what makes its service (in a directory of its own): in the order the tests need them, but the
# longest second, to have the second thread from the start.
SERVICES: dict[str, Callable[[Path], Server]] = {
    "fresh_service": start_fresh,
    "head_service": start_head,
    "wide_service": start_wide,
    "token_service": start_token,
    "server": start_field,
}


@pytest.fixture(scope="module", autouse=True)
def ahead(request, tmp_path_factory) -> Iterator[dict[str, Future[Server]]]:
    """The services of SERVICES that the selected tests name, being made."""
    named = {name for item in request.session.items if getattr(item, "module", None) is request.module
             for name in item.fixturenames}
    futures: dict[str, Future[Server]] = {}
    if missing_browser():  # the tests that would use them are skipped (or failed) without it
        yield futures
        return
    with ThreadPoolExecutor(2) as pool:
        for name, start in SERVICES.items():
            if name in named:
                futures[name] = pool.submit(start, tmp_path_factory.mktemp(name))
        yield futures
    for future in futures.values():  # the module's; the others' were stopped after their test if it ran
        if future.exception() is None:
            future.result().stop()


def service(ahead: dict[str, Future[Server]], name: str) -> Iterator[Server]:
    """The test's own service, stopped after it."""
    server = ahead[name].result()
    yield server
    server.stop()


@pytest.fixture(scope="module")
def fresh_service(ahead) -> Server:
    """A fresh install (no dataset, no version) for the versions' test, then the banner's."""
    return ahead["fresh_service"].result()


@pytest.fixture
def wide_service(ahead) -> Iterator[Server]:
    """A dataset, WIDE, whose one image is 2048 px wide."""
    yield from service(ahead, "wide_service")


@pytest.fixture
def token_service(ahead) -> Iterator[Server]:
    """A fresh install with an API token, TOKEN."""
    yield from service(ahead, "token_service")


@pytest.fixture
def head_service(ahead) -> Iterator[Server]:
    """A head's dataset and its calibration (start_head)."""
    yield from service(ahead, "head_service")


@pytest.fixture(scope="module")
def server(ahead) -> Server:
    """The loop's: a fresh install (no version) with one simulated dataset, "field" (2 pairs, 256x128)."""
    return ahead["server"].result()


# -- many versions, live updates, an unreachable service --------------------------------------------------------
def live_sizes(driver, since_ms: float = 0.0) -> list[int]:
    """Body sizes (bytes) of the /ui/live answers to requests made after ``since_ms`` (the page's
    performance.now()), in the order they came. Answers only: a request given up on has an entry too (size 0)."""
    return driver.execute_script("return performance.getEntriesByType('resource').filter(e => e.name.includes("
                                 "'/ui/live') && e.startTime > arguments[0] && e.responseStatus === 200)"
                                 ".map(e => e.decodedBodySize);", since_ms)


def test_versions_paged_and_live_diffs(browser, fresh_service):
    """25 versions: the newest 10 on the page, 10 more per click; /ui/live sends only parts that changed; HEAD /
    answers."""
    server = fresh_service
    try:
        with server.client() as client:
            for k in range(25):
                body = {"T_camera_lidar": {"rpy_deg": [0.0, 15.0, -55.0 + 0.01 * k], "xyz_m": [0.1, 0.05, -0.15]}}
                assert client.post("/extrinsics/versions", json=body).status_code == 201
            head = client.head("/")
            assert head.status_code == 200 and head.headers["content-type"].startswith("text/html")
        browser.get("about:blank")
        console_errors(browser)  # drained: an earlier test's page may have polled its stopped service
        with fast_timers(browser, POLL_CLOCK):  # polls every 0.5 s: the two waited for take ~1 s, not 9 s
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
        since = browser.execute_script("return performance.now()")
        until(browser, 10, lambda d: len(live_sizes(d, since)) >= 2)  # two of the page's own polls
        assert min(live_sizes(browser, since)[-2:]) < 600, live_sizes(browser)
        with server.client() as client:
            client.post("/extrinsics/versions", json={"T_camera_lidar": {"rpy_deg": [0, 15, -54], "xyz_m": [0, 0, 0]}})
        until(browser, 10, lambda d: numbers(d)[:2] == [26, 25])
        assert len(numbers(browser)) == 26  # all still shown: the page asks for as many as it shows
        assert console_errors(browser) == []
    finally:
        browser.get("about:blank")


def test_banner_while_the_service_does_not_answer(browser, fresh_service):
    """The banner while the service does not answer (SIGSTOP: connections hang), gone when it answers again.
    The versions' service: what the test before left on it changes nothing here."""
    server = fresh_service
    try:
        browser.get("about:blank")
        console_errors(browser)
        with fast_timers(browser, BANNER_CLOCK):  # the stopped service given up on after 2 s, not 8 s
            load(browser, server.url + "/")
        until(browser, 10, lambda d: live_sizes(d))  # the page's polls were answered
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


def test_a_restart_during_a_job_says_it_was_interrupted_and_offers_it_again(browser, fresh_service):
    """rigd serve stopped during a calibration the page started, and started again: the message does not keep
    "running" while nothing answers, then says the job was interrupted with a button that runs it again; an image
    asked for while the service was down is loaded once it answers. The versions' service, restarted."""
    server = fresh_service
    simulated_dataset(server.data_dir, "restart")
    try:
        browser.get("about:blank")
        console_errors(browser)
        with fast_timers(browser, BANNER_CLOCK):
            load(browser, server.url + "/")
        click(browser, 'button[data-action="pairs"][data-dataset="restart"]')
        until(browser, 10, lambda d: "/pairs/0/image" in lens_state(d)["after"]["src"] and images_loaded(d))
        click(browser, 'button[data-action="calibrate"][data-dataset="restart"]')
        started = re.compile(r"Calibration of restart from version \d+, the active one: job")
        until(browser, 10, lambda d: started.match(message(d)[0]))
        with server.client() as client:
            job = client.get("/jobs", params={"kind": "calibrate"}).json()[0]
            wait_running(client, job["id"])
        assert server.stop() in (0, -signal.SIGTERM)  # uvicorn re-raises the signal after a clean shutdown
        until(browser, 30, lambda d: d.find_element(By.ID, "offline").is_displayed())
        until(browser, 10, lambda d: "what became of it is not known" in message(d)[0])
        assert message(browser)[1] == "warn"
        click(browser, '#viewer-pairs button[data-pair="1"]')  # asked for while nothing answers: it fails
        until(browser, 10, lambda d: d.execute_script(
            "const i = document.getElementById('lens-after'); return i.getAttribute('src').includes('/pairs/1/')"
            " && i.complete && i.naturalWidth === 0"))
        server.start(same_port=True)
        until(browser, 30, lambda d: not d.find_element(By.ID, "offline").is_displayed())
        until(browser, 10, lambda d: f"job {job['id']} was interrupted" in message(d)[0])
        assert message(browser)[1] == "bad" and "run it again" in message(browser)[0]
        until(browser, 10, lambda d: images_loaded(d, ("lens-after",)))  # loaded again, not left broken
        click(browser, '#message button[data-action="rerun"]')
        with server.client() as client:
            until(browser, 10, lambda d: len(client.get("/jobs", params={"kind": "calibrate"}).json()) == 2)
            again = client.get("/jobs", params={"kind": "calibrate"}).json()[0]
            assert again["id"] != job["id"] and again["params"]["dataset"] == "restart"
            assert again["params"]["request"]["start"] == job["params"]["request"]["start"]
            client.delete(f"/jobs/{again['id']}")
            assert wait_job(client, again["id"], 60)["status"] in ("cancelled", "succeeded")
        until(browser, 10, lambda d: f"Run again of job {job['id']}: job {again['id']}" in message(d)[0])
        assert console_errors(browser, allowed=("/ui/live", "/pairs/1/", "net::ERR_CONNECTION_REFUSED")) == []
    finally:
        browser.get("about:blank")


def big_pair(data: Path, name: str, width: int = 2048) -> str:
    """A one-pair dataset whose image is ``width`` px wide (a small simulated pair's image, enlarged)."""
    root = simulated_dataset(data, name, pairs=1)
    image_path = root / "pairs" / "0000" / "image.png"
    image = cv2.imread(str(image_path))
    cv2.imwrite(str(image_path), cv2.resize(image, (width, width // 2), interpolation=cv2.INTER_NEAREST))
    rig = yaml.safe_load((root / "rig.yaml").read_text())
    rig["camera"].update(width=width, height=width // 2)
    (root / "rig.yaml").write_text(yaml.safe_dump(rig))
    return root.name


def test_zoom_loads_full_resolution_and_pans(browser, wide_service):
    """A 2048-px image: the lens loads a copy as wide as it first, the file itself once zoomed past that copy;
    1:1 shows one image pixel per screen pixel; a drag pans, within the image."""
    server, name = wide_service, WIDE
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
        drag(browser, lens, 100, 40)
        x1, y1 = translate(lens_state(browser)["after"]["transform"])
        assert (x1 - x0, y1 - y0) == pytest.approx((min(100, -x0), min(40, -y0)), abs=1.5)  # clamped at the edge
        for _ in range(12):  # far past the top left corner: the image's corner stays at the lens's
            drag(browser, lens, 150, 60)
        assert translate(lens_state(browser)["after"]["transform"]) == (0, 0)
        assert console_errors(browser) == []
    finally:
        browser.get("about:blank")


# -- the token, a head ------------------------------------------------------------------------------------------
def test_page_asks_for_the_token_and_sends_it(browser, token_service):
    server = token_service
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


def lens_and_figure_srcs(driver) -> dict[str, str]:
    return driver.execute_script(
        "const out = {}; for (const id of ['lens-before', 'lens-after', 'ov-closeup', 'ov-cloud'])"
        " out[id] = document.getElementById(id).getAttribute('src') || ''; return out;")


def test_page_picks_the_sensor_of_a_head(browser, head_service, figures):
    """A multi-camera head's version: a sensor picker beside the pair's overlays (the report's sensors, the
    first chosen), switching before, after and the close-up to that sensor's files; the cloud stays per pair.
    Its captured pairs show each sensor's image too."""
    server = head_service  # its dataset calibrated (start_head)
    try:
        with server.client() as client:
            page = client.get("/").text
        sensors = [f"cam{k}" for k in range(5)]
        assert f'data-sensors="{",".join(sensors)}"' in page  # from the version's report, rendered by the server

        browser.get("about:blank")
        console_errors(browser)  # drained: an earlier test's page may have polled its stopped service
        with fast_timers(browser, POLL_CLOCK):  # a refresh of the parts comes every 0.5 s
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
        chosen = browser.execute_script("return performance.now()")
        until(browser, 10, lambda d: "&sensor=cam1" in lens_and_figure_srcs(d)["lens-after"])
        until(browser, 10, images_loaded)  # the files exist: 0000_cam1_*.png
        now = lens_and_figure_srcs(browser)
        assert all("&sensor=cam1" in now[s] for s in ("lens-before", "lens-after", "ov-closeup")), now
        assert now["ov-cloud"] == first["ov-cloud"]
        assert texts(browser, picker + ".current") == ["cam1"]
        assert "version 1, pair 0, cam1" in text(browser, "#viewer-title")

        # The choice survives a change of pair and the page's refresh of its parts: a second poll since the
        # choice is asked for only once the first has been shown.
        click(browser, '#viewer-pairs button[data-pair="1"]')
        until(browser, 10, lambda d: "/overlays/1.png" in lens_and_figure_srcs(d)["lens-after"])
        assert "&sensor=cam1" in lens_and_figure_srcs(browser)["lens-after"]
        until(browser, 10, lambda d: len(live_sizes(d, chosen)) >= 2)
        assert "&sensor=cam1" in lens_and_figure_srcs(browser)["lens-after"]
        assert texts(browser, picker + ".current") == ["cam1"]
        until(browser, 10, images_loaded)
        assert console_errors(browser) == []
        viewer = browser.find_element(By.ID, "viewer")
        full = browser.execute_script("return document.documentElement.scrollHeight")
        viewport(browser, DESKTOP[0], full)  # the whole card in the viewport
        viewer.screenshot(str(figures / "page-head-sensors.png"))
        browser.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})

        heads_captured_images(browser, sensors)
        assert console_errors(browser) == []
    finally:
        browser.get("about:blank")  # no page left polling the service stopped next


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


# -- a fresh install, the whole loop ----------------------------------------------------------------------------
def test_page_capture_in_the_clis_words(browser, server, figures):
    """A capture of 2 pairs from the simulated rig, started from the page: its progress in rigd capture's words
    (no state names), live, and the message following it to its end."""
    browser.get("about:blank")
    console_errors(browser)  # drained: an earlier test's page may have polled its stopped service
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
    # The Sensors card shows the capture's camera taking frames (not the probe's view of it), in local time.
    sensors = text(browser, '[data-part="sensors"]')
    assert "in use by capture job 1" in sensors and "absent" not in sensors, sensors
    shown_time, local = browser.execute_script("const t = document.querySelector('[data-part=sensors] time');"
                                               " return [t.textContent, new Date(t.dateTime).toLocaleTimeString()]")
    assert shown_time == local and "UTC" not in sensors
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


# The loop goes on, on the capture's service, in steps, each a test of its own (as one test they took three
# times what a test should): each takes up the service where the one before left it, so they run in this file's
# order, as pytest runs them.
def open_page(browser, server) -> None:
    """The page, at twice its pace (PAGE_CLOCK): these steps wait for its polls to show what the service did.
    Its images in (the viewer's of the newest calibration), as the page was when one test went on."""
    with fast_timers(browser, PAGE_CLOCK):
        load(browser, server.url + "/")
    until(browser, 10, images_loaded)
    assert console_errors(browser) == []


def version_1(server) -> dict:
    with server.client() as client:
        response = client.get("/extrinsics/versions/1")
    assert response.status_code == 200, "version 1 is test_page_calibrates_a_fresh_install's, which runs before"
    return response.json()


def test_page_fresh_install_shows_captured_pairs(browser, server):
    """Before any calibration: where the next one starts from, and the captured pairs looked at."""
    with fast_timers(browser, PAGE_CLOCK):
        first_load_s = load(browser, server.url + "/")
    print(f"\npage load (navigation start to load event) without versions: {first_load_s * 1000:.0f} ms")
    assert console_errors(browser) == []
    # A fresh install has no active version: calibrating starts from the rig file (or the global search).
    assert "none" in text(browser, '[data-part="summary"]')
    assert browser.find_element(By.ID, "init-select").get_attribute("value") == "rig"
    assert not browser.find_element(By.CSS_SELECTOR, '#init-select option[value="active"]').is_enabled()
    # "activate if trusted" unticked: the page says a trusted first version is activated all the same.
    assert not browser.find_element(By.ID, "auto-activate").is_selected()
    assert "a trusted first version is activated either way" in text(browser, "#first-activation")
    assert text(browser, '[data-dataset="field"] .start-note') == "Calibrate starts from its rig file's guess"
    captured_pairs_before_calibrating(browser, server)
    assert console_errors(browser) == []


def test_page_calibrates_a_fresh_install(browser, server):
    """The first calibration, started from the page: it runs, its verdict in its colour, the message."""
    open_page(browser, server)
    first_calibration(browser, server)
    assert console_errors(browser) == []


def test_page_overlays_activation_and_advice(browser, server):
    """Version 1: its overlays, its activation confirmed, its advice's actions and the calibration options."""
    v1 = version_1(server)
    open_page(browser, server)
    before_after_zoom_and_pan(browser, server, v1)
    activate_with_confirmation(browser, server, v1)
    advice_and_options(browser, server, v1)
    assert console_errors(browser) == []


def test_page_change_check_and_layout(browser, server, figures):
    """A manual version's change, a check with every reason; the page's layout on a desktop and a phone."""
    assert version_1(server)["status"] == "active", "test_page_overlays_activation_and_advice activates it"
    open_page(browser, server)
    manual_version_and_change(browser, server)
    check_with_every_reason(browser, server)

    assert console_errors(browser) == []
    loaded_s = load(browser, server.url + "/")  # with datasets, jobs and versions to render
    until(browser, 10, images_loaded)
    assert console_errors(browser) == []
    print(f"\npage load (navigation start to load event) "
          f"with {len(browser.find_elements(By.CSS_SELECTOR, '[data-part=datasets] .row'))} datasets, "
          f"{len(browser.find_elements(By.CSS_SELECTOR, '.job'))} jobs, 2 versions: {loaded_s * 1000:.0f} ms")
    screenshot(browser, figures / "page-desktop.png", DESKTOP, mobile=False)

    # At a phone's width: nothing wider than the screen, the buttons still there.
    screenshot(browser, figures / "page-phone.png", PHONE, mobile=True)
    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                            {"width": PHONE[0], "height": PHONE[1], "deviceScaleFactor": 1, "mobile": True})
    assert browser.execute_script("return document.documentElement.scrollWidth") <= PHONE[0]
    assert browser.find_element(By.CSS_SELECTOR, 'button[data-action="calibrate"]').is_displayed()
    # A camera warning with a long path (as rigd.api.sensors words it) wraps: the page stays the screen's width
    # (it was 468 px); every versions table's z column lies inside its card.
    browser.execute_script("const dd = document.querySelectorAll('[data-part=sensors] dd')[1];"
                           " const w = document.createElement('span'); w.className = 'warn'; w.textContent ="
                           " 'cannot read /sys/module/usbcore/parameters/usbfs_memory_mb; check"
                           " usbcore.usbfs_memory_mb by hand'; dd.append(document.createElement('br'), w);")
    assert browser.execute_script("return document.documentElement.scrollWidth") <= PHONE[0]
    assert browser.execute_script("return [...document.querySelectorAll('table.axes')].every(t =>"
                                  " t.querySelector('thead th:last-child').getBoundingClientRect().right"
                                  " <= t.closest('.card').getBoundingClientRect().right)")
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
    # Its help speaks of what is there: no dots, no before | after.
    assert not browser.find_element(By.ID, "lens-help").is_displayed()
    help_text = text(browser, "#lens-help-pair")
    assert "zoom" in help_text and "before" not in help_text and "Dots" not in help_text
    assert text(browser, "#pair-meta").startswith("simulated · indoor scene")  # the pair's meta.yaml, in words
    assert "range noise 2 cm" in text(browser, "#pair-meta")
    click(browser, '#viewer-pairs button[data-pair="1"]')
    until(browser, 10, lambda d: "/pairs/1/image" in lens_state(d)["after"]["src"])
    until(browser, 10, images_loaded)


def first_calibration(browser, server) -> dict:
    """Calibrate from the page as it was left (no choice of start): the job's verdict shown in its colour."""
    click(browser, 'button[data-action="calibrate"][data-dataset="field"]')
    until(browser, 10, lambda d: d.find_elements(By.CSS_SELECTOR, '.job[data-kind="calibrate"]'))
    browser.refresh()  # a reload mid-job: the message still follows the job to its verdict
    shown = watch(browser, '.job[data-kind="calibrate"]', lambda t: finished(browser, '.job[data-kind="calibrate"]'),
                  240)
    assert any("running" in s for s in shown), shown
    assert len(shown) >= 2, shown  # the stage moved on while it ran (edges, optimising, overlays)
    with server.client() as client:
        job = client.get("/jobs", params={"kind": "calibrate"}).json()[0]
        assert job["params"]["request"]["start"] in ("rig", "search") and job["status"] == "succeeded", job
        v1 = client.get("/extrinsics/versions/1").json()
    verdict = v1["verdict"]["status"]
    badge = browser.find_element(By.CSS_SELECTOR, '.job[data-kind="calibrate"] .badge')
    assert badge.text == f"verdict {verdict}" and verdict in badge.get_attribute("class").split()
    assert "succeeded" not in text(browser, '.job[data-kind="calibrate"]')
    until(browser, 10, lambda d: "version 1, verdict" in message(d)[0])
    assert message(browser)[0].startswith(f"Calibration of field from its rig file's guess: job {job['id']} done: "
                                          f"version 1, verdict {verdict}"), message(browser)
    assert message(browser)[1] == TONE[verdict]
    # "activate if trusted" was unticked: a trusted first version is active all the same, and the page says why.
    assert ("activated: the first version" in message(browser)[0]) == (v1["status"] == "active")
    until(browser, 10, lambda d: d.find_elements(By.ID, "v1"))
    return v1


def before_after_zoom_and_pan(browser, server, v1: dict) -> None:
    """The version's overlays: before and after at the same place, zoomed and panned together."""
    click(browser, '#v1 button[data-action="view"]')
    until(browser, 10, lambda d: "version 1, pair 0" in text(d, "#viewer-title"))
    until(browser, 10, lambda d: images_loaded(d, ("lens-before", "lens-after", "ov-closeup", "ov-cloud")))
    state = lens_state(browser)
    assert "stage=after" in state["after"]["src"] and not state["after"]["hidden"] and state["before"]["hidden"]
    assert "before (initial guess)" in text(browser, "#lens-help") and not text(browser, "#lens-help-pair")
    assert state["after"]["natural"] == v1["quality"]["image_size_px"][0]  # the overlay at full resolution
    click(browser, "#viewer button[data-zoom=in]")
    click(browser, "#viewer button[data-zoom=in]")
    assert lens_state(browser)["zoom"] == pytest.approx(2.25, abs=1e-3)
    lens = browser.find_element(By.ID, "lens")
    drag(browser, lens, -60, -25)
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
    """An untrusted version asks first, with its reasons; keeping the active one changes nothing. A failed one is
    not offered at all: the expert who wants it anyway uses the API, and the header then shows its verdict."""
    if v1["status"] == "active":  # a trusted first version is active at once: nothing to confirm
        assert v1["verdict"]["status"] == "trusted"
        return
    if v1["verdict"]["status"] == "failed":
        assert not browser.find_elements(By.CSS_SELECTOR, '#v1 button[data-action="activate"]')
        assert "do not use it" in text(browser, "#v1 .bad-note")
        with server.client() as client:
            assert client.post("/extrinsics/versions/1/activate").json()["status"] == "active"
        until(browser, 10, lambda d: attr(d, "#v1", "data-status") == "active")
    else:
        click(browser, '#v1 button[data-action="activate"]')
        until(browser, 5, lambda d: d.find_element(By.ID, "confirm").is_displayed())
        assert texts(browser, "#confirm-reasons li") == [page_words(r) for r in v1["verdict"]["reasons"]]
        assert v1["verdict"]["status"] in text(browser, "#confirm-lead")
        weak = ", ".join(v1["verdict"]["weak_axes"])
        assert text(browser, "#confirm-unknown") == f"Not known to the tolerance: {weak}."
        click(browser, "#confirm-no")
        assert not browser.find_element(By.ID, "confirm").is_displayed()
        with server.client() as client:
            assert client.get("/extrinsics/versions/1").json()["status"] == "candidate"
        click(browser, '#v1 button[data-action="activate"]')
        click(browser, "#confirm-yes")
        until(browser, 10, lambda d: attr(d, "#v1", "data-status") == "active")
        assert message(browser)[1] == "warn"  # not a green "active" for a weak version
    status = v1["verdict"]["status"]  # the header says what is active, in its verdict's colour
    until(browser, 10, lambda d: text(d, "#active-verdict") == status)
    assert status in attr(browser, "#active-verdict", "class").split()
    until(browser, 10, lambda d: not d.find_element(By.ID, "first-activation").is_displayed())
    # With an active version the next calibration starts from it (the operator did not choose otherwise).
    until(browser, 10, lambda d: d.find_element(By.ID, "init-select").get_attribute("value") == "active")


def advice_and_options(browser, server, v1: dict) -> None:
    """The advice's actions fill the page's options; a calibration sends them (then it is cancelled)."""
    steps = v1["verdict"].get("next_steps") or []
    assert bool(steps) == (v1["verdict"]["status"] != "trusted")
    if steps:
        assert texts(browser, "#v1 .next-steps li")[0].startswith(steps[0]["text"])
        # Fewer than 12 pairs: the advice asks for more, one count in all, and its button prepares that capture.
        counts = [step["pairs"] for step in steps if "capture" in step["actions"] and step["pairs"]]
        click(browser, '#v1 button[data-advice="capture"]')
        assert browser.find_element(By.NAME, "dataset").get_attribute("value") == "field"
        assert browser.find_element(By.NAME, "n").get_attribute("value") == str(max(counts))
        assert f"up to {max(counts)} in all (it holds 2 now)" in message(browser)[0]
    # A capture that would write nothing (2 pairs in all into a dataset of 2) says so before it starts.
    browser.find_element(By.NAME, "dataset").clear()
    browser.find_element(By.NAME, "dataset").send_keys("field")
    browser.find_element(By.NAME, "n").clear()
    browser.find_element(By.NAME, "n").send_keys("2")
    click(browser, "#capture-form button[type=submit]")
    assert message(browser) == ("Dataset field holds 2 pairs already: a capture to 2 pairs in all would write "
                                'none. Set "pairs in all" above 2 to add pairs.', "bad")
    with server.client() as client:
        assert client.get("/jobs", params={"kind": "capture"}).json()[0]["params"]["dataset"] == "captured"
    # A dataset id the service would refuse: the page says what an id may hold, not only "match the format".
    browser.find_element(By.NAME, "dataset").clear()
    browser.find_element(By.NAME, "dataset").send_keys("site a/2")
    click(browser, "#capture-form button[type=submit]")
    assert message(browser)[0].startswith("dataset id: 1 to 64 letters, digits, '_', '.' or '-'")
    browser.find_element(By.NAME, "dataset").clear()
    browser.execute_script("document.getElementById('calibrate-options').open = true")
    # The lever arm in cm, as the versions table shows it; a comma read as the decimal mark ("1,5" is 1.5, not 15).
    assert "in cm" in text(browser, '#calibrate-form fieldset[data-group="lever arm"] legend')
    # The lever arm typed in metres into the cm fields, first without its ±: the ± field is marked, nothing sent.
    for name, value in (("prior-x", "0,1"), ("prior-y", "0.05"), ("prior-z", "-0.15"), ("tolerance-deg", "0,3"),
                        ("tolerance-cm", "2.5")):
        field = browser.find_element(By.NAME, name)
        field.clear()
        field.send_keys(value)
    browser.find_element(By.NAME, "fix-translation").click()
    click(browser, 'button[data-action="calibrate"][data-dataset="field"]')
    sigma = browser.find_element(By.NAME, "prior-sigma-cm")
    assert sigma.get_attribute("validationMessage").startswith("lever arm ±: empty; give how well the drawing")
    assert message(browser) == (sigma.get_attribute("validationMessage"), "bad")
    sigma.send_keys("1,5")
    # With its ±: the page asks whether these were metres (all three under 1 cm) and offers them in cm.
    click(browser, 'button[data-action="calibrate"][data-dataset="field"]')
    until(browser, 5, lambda d: d.find_element(By.ID, "lever-check").is_displayed())
    assert "Were these metres? In cm they are 10, 5, -15." in text(browser, "#lever-said")
    click(browser, "#lever-fix")
    assert [browser.find_element(By.NAME, f"prior-{a}").get_attribute("value") for a in "xyz"] == ["10", "5", "-15"]
    until(browser, 10, lambda d: len(d.find_elements(By.CSS_SELECTOR, '.job[data-kind="calibrate"]')) == 2)
    with server.client() as client:
        job = client.get("/jobs", params={"kind": "calibrate"}).json()[0]
    assert job["params"]["request"]["options"]["prior"] == {"xyz_m": [0.1, 0.05, -0.15], "sigma_cm": 1.5,
                                                          "rpy_deg": None, "sigma_deg": None}
    options = job["params"]["request"]["options"]
    assert options["fix_translation"] is True
    assert options["tolerance"] == {"rotation_deg": 0.3, "translation_cm": 2.5, "rpy_deg": None, "xyz_cm": None}
    options = "lever arm (10, 5, -15) ± 1.5 cm, translation fixed, tolerance 0.3° / 2.5 cm"
    assert options in text(browser, f'[data-job="{job["id"]}"]')
    click(browser, f'button[data-action="cancel"][data-job="{job["id"]}"]')
    until(browser, 30, lambda d: f"job {job['id']} cancelled" in message(d)[0])
    # An out-of-range value or one that is no number is refused by the page before any request, saying the
    # range and unit. The page calls fetch() within the click's handler, before its first await: a fetch spy that
    # saw no request once the click returned is certain, where a pause before asking only made a late one unlikely.
    browser.execute_script("window.sent = []; window.realFetch = window.fetch; window.fetch = (url, init) => {"
                           " window.sent.push(url); return window.realFetch(url, init); };")
    for name, value, words in (("tolerance-deg", "50", "rotation tolerance: must be within 0.001 .. 10 °, got 50"),
                               ("prior-x", "934", "lever arm x: must be within -500 .. 500 cm, got 934"),
                               ("prior-sigma-cm", "1,000.5", "lever arm ±: not a number (write 1.5 or 1,5)")):
        field = browser.find_element(By.NAME, name)
        field.clear()
        field.send_keys(value)
        click(browser, 'button[data-action="calibrate"][data-dataset="field"]')
        assert browser.execute_script("return window.sent.filter(u => !u.startsWith('/ui/live'))") == []
        assert words in browser.execute_script("return document.getElementsByName(arguments[0])[0]"
                                               ".validationMessage", name)
        assert message(browser) == (browser.find_element(By.NAME, name).get_attribute("validationMessage"), "bad")
        field.clear()
        field.send_keys({"tolerance-deg": "0.3", "prior-x": "10", "prior-sigma-cm": "1.5"}[name])
    with server.client() as client:
        assert len(client.get("/jobs", params={"kind": "calibrate"}).json()) == 2
    browser.execute_script("window.fetch = window.realFetch")
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
    # Bold only what stands out (no sigma for a manual version: what the table shows as a change), not +0.00.
    weights = browser.execute_script("return [...document.querySelectorAll('#v2 tr.change td')].map(td =>"
                                     " Number(getComputedStyle(td).fontWeight))")
    assert [w > 600 for w in weights] == [abs(c) >= 0.005 for c in change], (weights, change)
    assert weights[4] < 600 and weights[5] < 600 and weights[3] > 600
    assert np.linalg.norm(change[:3]) == pytest.approx(0.5, abs=0.015)  # deg, the rotation between them
    click(browser, '#v2 button[data-action="activate"]')
    until(browser, 5, lambda d: d.find_element(By.ID, "confirm").is_displayed())
    assert "no verdict" in text(browser, "#confirm-lead")
    # How far it moves the rig's extrinsics, per axis and in all, and that nothing measured it.
    move = text(browser, "#confirm-move")
    assert "x +3.00 cm, y +0.00 cm, z +0.00 cm (in all 0.50° and 3.0 cm) from version 1" in move, move
    assert "Nothing measured" in text(browser, "#confirm-unknown")
    assert "from the total station" in text(browser, "#confirm-reasons")
    click(browser, "#confirm-yes")
    until(browser, 10, lambda d: attr(d, "#v2", "data-status") == "active")
    assert attr(browser, "#v1", "data-status") == "superseded"
    assert "version 2" in text(browser, '[data-part="summary"]')
    assert message(browser) == ("Version 2 is active. It has no verdict: nothing measured it.", "warn")


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
    assert texts(browser, row + " .reasons li") == [page_words(r) for r in check["result"]["reasons"]]
    groups = check["result"]["groups"]  # each judged group's length against its threshold (none here: few places)
    lengths = texts(browser, row + " .lengths li")
    assert len(lengths) == len(groups)
    for line, (name, g) in zip(lengths, sorted(groups.items()), strict=True):
        unit = "°" if name == "rotation" else " cm"
        assert line.startswith(f"{name} moved by {g['length']:.2f}{unit} (threshold {g['threshold']:g}{unit})")
    assert text(browser, row + " .badge") == status
    assert text(browser, row + " b").endswith("check") and "check version 2 on field" in text(browser, row)
    until(browser, 10, lambda d: f"job {check['id']} done: version 2 on field: {status}" in message(d)[0])
    assert message(browser)[1] == TONE[status]


# -- without a browser ------------------------------------------------------------------------------------------
def test_only_a_heads_report_lists_sensors():
    """One camera's (or a manual) version has no sensors to pick; a head's are its report's, in order."""
    from rigd.web.versions_view import report_sensors

    assert report_sensors({"pairs": [{"edge_pixels": 10, "edge_points": 5}]}) == []
    assert report_sensors({}) == []
    head = {"pairs": [{"edge_pixels": 3, "edge_pixels_per_sensor": {"cam0": 1, "cam1": 2}}]}
    assert report_sensors(head) == ["cam0", "cam1"]


def test_the_page_acts_on_the_advice_records_not_their_words():
    """A button per action the page can take, from the step's record (rewording the advice changes no button);
    a report stored before steps were records keeps its words and has no button."""
    from rigd.calibration.advice import Action, Step
    from rigd.calibration.sections import step_yaml
    from rigd.web.versions_view import ADVICE_BUTTONS, advice_actions, capture_target

    step = step_yaml(Step("any words at all", (Action.CAPTURE,), (), 12))
    assert advice_actions(step) == [("capture", "Capture more pairs")]
    both = step_yaml(Step("other words", (Action.LEVER_ARM, Action.FIX_TRANSLATION, Action.FIT_ELEVATION)))
    assert advice_actions(both) == [("prior", "Give the lever arm"), ("fix", "Fix the translation")]
    assert set(ADVICE_BUTTONS) <= {a.value for a in Action}
    assert capture_target([step, both, "only 2 pairs: rigd is measured with 12 (rigd capture --n 12)"]) == 12


def test_live_reads_only_known_parts():
    from rigd.web.routes import known_hashes

    assert known_hashes("jobs:ab12,versions:cd34,bogus:1,,summary") == {"jobs": "ab12", "versions": "cd34",
                                                                        "summary": ""}
