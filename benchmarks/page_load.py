"""Load time of ``rigd serve``'s operator page in headless Chromium (target: <= 1 s locally with 1,000 versions).

Run: .venv/bin/python benchmarks/page_load.py [--pairs 6] [--width 1024] [--versions 1000] [--loads 20]
Starts ``rigd serve`` on a loopback port with a fresh data directory holding a simulated dataset, calibrates
it (overlays at the dataset's size), stores ``--versions`` more versions, then opens the page ``--loads``
times in Debian's Chromium (chromium-driver, as tests/rigd/api/test_page.py) and prints, per load, the time
from navigation start to the load event and to the overlay images decoded: the first load (empty cache)
and the median and maximum of the others. Then the sizes of ``GET /`` and ``GET /ui/live`` (all parts, and
nothing changed: what the page polls) and the server's time for each (median of 20, one keep-alive client).
"""

from __future__ import annotations

import argparse
import signal
import statistics
import tempfile
import time
from pathlib import Path

import httpx
from api_status_latency import bench_data_dir, free_port, start
from selenium import webdriver
from selenium.webdriver.chrome.service import Service as DriverService
from selenium.webdriver.support.ui import WebDriverWait

LOADED = """
const n = performance.getEntriesByType('navigation')[0];
return n && n.loadEventEnd > 0 ? n.loadEventEnd : null;
"""
DECODED = """
const imgs = ['lens-after', 'ov-closeup'].map(id => document.getElementById(id));
return imgs.every(i => i.getAttribute('src') && i.complete && i.naturalWidth > 0) ? performance.now() : null;
"""


def browser() -> webdriver.Chrome:
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--window-size=1280,900"):
        options.add_argument(arg)
    return webdriver.Chrome(options=options, service=DriverService("/usr/bin/chromedriver"))


def load(driver: webdriver.Chrome, url: str) -> tuple[float, float]:
    """(load event, overlays decoded) in ms after navigation start; the viewer (its close-up loaded lazily) is
    scrolled to at the load event; the second figure is polled (+<= 20 ms)."""
    driver.get(url)
    wait = WebDriverWait(driver, 30, poll_frequency=0.02)
    loaded = wait.until(lambda d: d.execute_script(LOADED))
    driver.execute_script("document.getElementById('viewer').scrollIntoView()")
    return loaded, wait.until(lambda d: d.execute_script(DECODED))


def timed_get(client: httpx.Client, url: str, params: dict[str, str] | None = None) -> tuple[float, list[int]]:
    """(median ms, the answers' sizes in bytes) of 20 GETs of ``url``."""
    times, sizes = [], []
    for _ in range(20):
        started = time.perf_counter()
        response = client.get(url, params=params)
        times.append((time.perf_counter() - started) * 1e3)
        sizes.append(len(response.content))
    return statistics.median(times), sizes


def served(client: httpx.Client) -> None:
    """What the page costs the server: GET /, /ui/live with every part, /ui/live when nothing changed."""
    hashes = client.get("/ui/live").json()["hashes"]
    unchanged = {"have": ",".join(f"{name}:{value}" for name, value in hashes.items())}
    for label, url, params in (("GET /", "/", None), ("GET /ui/live, all parts", "/ui/live", None),
                               ("GET /ui/live, nothing new", "/ui/live", unchanged)):
        ms, sizes = timed_get(client, url, params)
        print(f"{label:26s} {min(sizes) / 1000:5.1f}-{max(sizes) / 1000:.1f} kB  median {ms:6.1f} ms "
              "(server, one keep-alive client; the sensors' part changes with each sensor check)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=6)
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--versions", type=int, default=1000)
    parser.add_argument("--loads", type=int, default=20)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data, init = bench_data_dir(Path(tmp), args.pairs, args.width)
        port = free_port()
        proc = start(data, port)
        driver = browser()
        try:
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10) as client:
                link = client.post("/calibrate", json={"dataset": "bench", "init": init}).headers["Location"]
                while (job := client.get(link).json())["status"] in ("queued", "running"):
                    time.sleep(0.5)
                if job["status"] != "succeeded":
                    raise SystemExit(f"the calibration {job['status']}: {job['error']}")
                started = time.perf_counter()
                for i in range(args.versions):
                    client.post("/extrinsics/versions", json={"T_camera_lidar": {
                        "rpy_deg": [r + 0.001 * i for r in init["rpy_deg"]], "xyz_m": init["xyz_m"]}})
                print(f"stored {args.versions} versions in {time.perf_counter() - started:.1f} s")
                served(client)
            url = f"http://127.0.0.1:{port}/"
            times = [load(driver, url) for _ in range(args.loads)]
            print(f"page: {args.versions + 1} versions, {args.pairs} pairs {args.width}x{args.width // 2}; "
                  f"{args.loads} loads in headless Chromium (navigation start to ...)")
            for label, k in (("load event", 0), ("overlays decoded", 1)):
                warm = [t[k] for t in times[1:]]
                print(f"{label:18s} first {times[0][k]:6.0f} ms   then median {statistics.median(warm):6.0f} ms  "
                      f"max {max(warm):6.0f} ms")
        finally:
            driver.quit()
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=60)


if __name__ == "__main__":
    main()
