#!/usr/bin/env python3
"""Browser test of the farm's contact sheet (index.html of `plantview render --views`).

Generates preset a into a temporary store, renders a views file of eight views around the plant,
opens DIR/index.html from disk (file://, no server) in headless Chromium through chromedriver,
and checks that the page lists every view with its image loaded and that the filter box narrows
the list by name. Leaves a screenshot of the page.

    tests/browser/test_contact_sheet.py --plantview build/service/plantview
                                        [--screenshot build/browser/contact_sheet.png]

Exit status: 0 passed, 1 failed (with a message naming the step), 77 skipped (no chromium or
chromedriver). The WebDriver client and process helpers are the viewer test's (test_viewer.py).
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_viewer import (CHROMEDRIVER, CHROMIUM, Failure, WebDriver, free_port, http_json,  # noqa: E402
                         log_tail, start_process, stop_process, wait_for)

VIEWS = 8
PAGE_S = 30  # until every thumbnail has loaded

PAGE_JS = """
const cards = [...document.querySelectorAll('figure.view')];
return {names: cards.map(c => c.dataset.name),
        shown: cards.filter(c => c.style.display !== 'none').map(c => c.dataset.name),
        loaded: cards.filter(c => { const i = c.querySelector('img');
                                    return i && i.complete && i.naturalWidth > 0; }).length,
        summary: (document.getElementById('summary') || {}).innerText};
"""


def views_around(bounds, count):
    """Views file JSON: `count` overview views at even angles around the plant's bounds."""
    lo, hi = bounds["min"], bounds["max"]
    centre = [(a + b) / 2 for a, b in zip(lo, hi)]
    radius = max(b - a for a, b in zip(lo, hi))
    views = []
    for i in range(count):
        angle = 2 * math.pi * i / count
        eye = [centre[0] + radius * math.cos(angle), centre[1] + radius * math.sin(angle),
               centre[2] + radius * 0.5]
        views.append({"name": f"around-{i:02d}", "title": f"Plant from {round(math.degrees(angle))} degrees",
                      "kind": "overview",
                      "camera": {"eye": eye, "target": centre, "up": [0, 0, 1], "fov_deg": 50},
                      "aspect": 16 / 9, "subject": [], "attributes": {}})
    return {"version": 1, "per": "overview", "views": views}


def run(args, tmp):
    plantview = os.path.abspath(args.plantview)
    store, out = os.path.join(tmp, "store"), os.path.join(tmp, "out")
    subprocess.run([plantview, "gen", "--preset", "a", "--store", store], check=True)
    info = json.loads(subprocess.run([plantview, "info", "--json", "--store", store], check=True,
                                     capture_output=True).stdout)
    views_path = os.path.join(tmp, "views.json")
    with open(views_path, "w") as f:
        json.dump(views_around(info["bounds_m"], VIEWS), f)
    rendered = subprocess.run([plantview, "render", "--store", store, "--views", views_path,
                               "--out", out, "--size", "320x180"], capture_output=True, text=True)
    if rendered.returncode != 0:
        raise Failure(f"render --views exited {rendered.returncode}: {rendered.stderr}")
    names = [f"around-{i:02d}" for i in range(VIEWS)]

    driver_port = free_port()
    driver_log = os.path.join(tmp, "chromedriver.log")
    chromedriver = start_process([CHROMEDRIVER, f"--port={driver_port}"], driver_log)
    driver = WebDriver(f"http://127.0.0.1:{driver_port}")
    try:
        def driver_up():
            if chromedriver.poll() is not None:
                raise Failure(f"chromedriver exited:\n{log_tail(driver_log)}")
            try:
                status, reply = http_json(f"{driver.base}/status", timeout=5)
                return status == 200 and reply["value"]["ready"]
            except (OSError, KeyError, TypeError):
                return False
        wait_for("chromedriver to be ready", 30, driver_up)
        driver.start(CHROMIUM, ["--headless=new", "--no-sandbox", "--disable-gpu",
                                "--disable-dev-shm-usage", "--allow-file-access-from-files",
                                "--window-size=1400,1000"])
        driver.command("POST", "/url", {"url": "file://" + os.path.join(out, "index.html")})

        page = wait_for("every thumbnail to load", PAGE_S,
                        lambda: (lambda p: p if p and p["loaded"] == VIEWS else None)(driver.js(PAGE_JS)))
        if page["names"] != names:
            raise Failure(f"the sheet lists {page['names']}, expected {names}")
        if f"{VIEWS} views: {VIEWS} done" not in (page["summary"] or ""):
            raise Failure(f"summary says {page['summary']!r}")
        print(f"contact sheet lists {len(page['names'])} views, every image loaded", flush=True)

        driver.js("const f = document.getElementById('filter'); f.value = 'around-03';"
                  "f.dispatchEvent(new Event('input'));")
        shown = driver.js(PAGE_JS)["shown"]
        if shown != ["around-03"]:
            raise Failure(f"filtering by 'around-03' shows {shown}")
        driver.js("const f = document.getElementById('filter'); f.value = '';"
                  "f.dispatchEvent(new Event('input'));")
        if driver.js(PAGE_JS)["shown"] != names:
            raise Failure("clearing the filter does not show every view again")
        print("the filter box narrows the sheet by name", flush=True)
        if args.screenshot:
            driver.screenshot(args.screenshot)
            print(f"screenshot: {os.path.abspath(args.screenshot)}", flush=True)
    finally:
        driver.quit()
        stop_process(chromedriver)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plantview", required=True)
    parser.add_argument("--screenshot", default="")
    args = parser.parse_args()
    for tool in (CHROMIUM, CHROMEDRIVER):
        if not os.access(tool, os.X_OK):
            print(f"SKIP: {tool} is not installed (Debian: chromium, chromium-driver)", file=sys.stderr)
            return 77
    tmp = tempfile.mkdtemp(prefix="plantview-contact-sheet-")
    try:
        run(args, tmp)
    except (Failure, subprocess.CalledProcessError, OSError) as e:
        print(f"FAIL: {e}", file=sys.stderr)
        return 1
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print("PASS", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
