#!/usr/bin/env python3
"""Browser test of the viewer page (web/) against a running `plantview serve`.

Starts the server on a store, drives headless Chromium through chromedriver (the W3C WebDriver
protocol, JSON over HTTP, spoken here with urllib: no Selenium, standard library only), and checks
that the page shows a frame, orbits on a drag (with interactive frames, then a still at rest),
shows the picked object's attributes on a click, finds an object by the tag typed into its search
field (the attributes panel shows it, its box is drawn over the frame, and the camera flies to
frame it), says which quality the frame has (as the server reports it, where it does), and flies
back to the model's camera on Home. Leaves a screenshot of the page with the found object.

    tests/browser/test_viewer.py --plantview build/service/plantview [--store DIR]
                                 [--screenshot build/browser/viewer.png] [--port 0]

Exit status: 0 passed, 1 failed (with a message naming the step), 77 skipped (no chromium or
chromedriver; CTest's SKIP_RETURN_CODE). The server and chromedriver (with its Chromium) are
stopped however the test ends.
"""
import argparse
import base64
import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.parse
import urllib.request

REPO_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
WINDOW_SIZE = (1024, 768)
SERVER_START_S = 30      # until GET /api/model answers
FIRST_FRAME_S = 60       # frames are rendered on a CPU here: one can take a second or two
FRAME_S = 60             # for any later frame (or the still after a move)
PICK_S = 30              # one /api/pick answer
SEARCH_S = 30            # a search's /api/objects answer and the fly-to (0.8 s) after it
ENTER_KEY = "\ue007"     # WebDriver's Enter
ELEMENT_KEY = "element-6066-11e4-a52e-4f735466cecf"  # W3C WebDriver's element reference key
TOKEN = "browser-test-token"  # the server runs with --token: the page must send it


class Failure(Exception):
    """A check failed; the message says which and what was seen."""


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def http_json(url, method="GET", body=None, timeout=30, token=None):
    """Returns (status, decoded JSON body or None). Raises OSError when nothing answers."""
    data = None if body is None else json.dumps(body).encode()
    headers = {"Content-Type": "application/json"} if data else {}
    if token:
        headers["Authorization"] = f"Bearer {token}"
    request = urllib.request.Request(url, data=data, method=method, headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=timeout) as response:
            status, raw = response.status, response.read()
    except urllib.error.HTTPError as e:
        status, raw = e.code, e.read()
    try:
        return status, json.loads(raw) if raw else None
    except ValueError:
        return status, None


def wait_for(what, timeout_s, probe, interval_s=0.25):
    """Calls probe() until it returns a true value, which is returned; Failure after timeout_s."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = probe()
        if value:
            return value
        if time.monotonic() > deadline:
            raise Failure(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(interval_s)


def start_process(argv, log_path, cwd=None):
    """Starts argv in its own process group (so that its children can be stopped with it)."""
    log = open(log_path, "wb")
    try:
        return subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                cwd=cwd, start_new_session=True)
    finally:
        log.close()


def stop_process(process):
    """Stops a process started by start_process and its group: SIGTERM, then SIGKILL after 5 s."""
    if process is None:
        return
    for sig, wait_s in ((signal.SIGTERM, 5), (signal.SIGKILL, 5)):
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            break
        try:
            process.wait(wait_s)
            break
        except subprocess.TimeoutExpired:
            continue


def log_tail(path, lines=30):
    try:
        with open(path, "rb") as f:
            return "\n".join(f.read().decode(errors="replace").splitlines()[-lines:])
    except OSError:
        return "(no log)"


class WebDriver:
    """The few W3C WebDriver commands the test needs."""

    def __init__(self, base_url):
        self.base = base_url
        self.session = None

    def command(self, method, path, body=None, timeout=60):
        url = f"{self.base}/session/{self.session}{path}" if self.session else f"{self.base}{path}"
        status, reply = http_json(url, method, body, timeout)
        value = reply.get("value") if isinstance(reply, dict) else None
        if status != 200:
            detail = value.get("message", value) if isinstance(value, dict) else reply
            raise Failure(f"WebDriver {method} {path}: HTTP {status}: {str(detail)[:500]}")
        return value

    def start(self, chromium, args):
        capabilities = {"alwaysMatch": {"browserName": "chrome",
                                        "goog:chromeOptions": {"binary": chromium, "args": args}}}
        value = self.command("POST", "/session", {"capabilities": capabilities}, timeout=120)
        self.session = value["sessionId"]

    def quit(self):
        if self.session:
            try:
                self.command("DELETE", "", timeout=20)
            except (Failure, OSError):
                pass
            self.session = None

    def js(self, script, *args):
        """Runs a function body in the page; `return` gives the (JSON) result."""
        return self.command("POST", "/execute/sync", {"script": script, "args": list(args)})

    def pointer(self, steps):
        """Performs mouse actions (pointerMove/pointerDown/pointerUp dicts), then releases all."""
        self.command("POST", "/actions", {"actions": [{
            "type": "pointer", "id": "mouse", "parameters": {"pointerType": "mouse"},
            "actions": steps}]})
        self.command("DELETE", "/actions")

    def element(self, css):
        """The element reference of the first element matching a CSS selector."""
        value = self.command("POST", "/element", {"using": "css selector", "value": css})
        return value[ELEMENT_KEY]

    def type_into(self, css, text):
        """Focuses the element and types text into it, key by key (as a user does)."""
        self.command("POST", f"/element/{self.element(css)}/value", {"text": text})

    def click(self, css):
        self.command("POST", f"/element/{self.element(css)}/click", {})

    def screenshot(self, path):
        png = base64.b64decode(self.command("GET", "/screenshot"))
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        with open(path, "wb") as f:
            f.write(png)


def move(x, y, duration_ms=0):
    return {"type": "pointerMove", "origin": "viewport", "x": int(x), "y": int(y), "duration": duration_ms}


# The page's state, as the test reads it (window.plantview and #frame's geometry).
PAGE_STATE_JS = """
const p = window.plantview, f = document.getElementById('frame');
if (!p || !f) return null;
const r = f.getBoundingClientRect();
return {camera: p.camera, home: p.home, framesShown: p.framesShown, framesByMode: p.framesByMode,
        still: p.still,
        lastPick: p.lastPick, selected: p.selected, flying: p.flying, quality: p.quality,
        natural: [f.naturalWidth, f.naturalHeight], rect: [r.left, r.top, r.width, r.height],
        stats: document.getElementById('stats').innerText,
        pick: document.getElementById('pick').innerText};
"""

# How many pixels of the selection overlay are drawn (alpha > 0), and how many of them lie in the
# middle third of the canvas in each direction.
OVERLAY_PIXELS_JS = """
const c = document.getElementById('overlay');
if (!c || c.width === 0 || c.height === 0) return [0, 0];
const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
let all = 0, middle = 0;
for (let y = 0; y < c.height; ++y)
  for (let x = 0; x < c.width; ++x)
    if (d[4 * (y * c.width + x) + 3] > 0) {
      ++all;
      if (3 * x >= c.width && 3 * x < 2 * c.width && 3 * y >= c.height && 3 * y < 2 * c.height) ++middle;
    }
return [all, middle];
"""


def camera_query(camera, w, h):
    """The page's camera query (JSON numbers print back to the same doubles)."""
    vec = lambda v: ",".join(repr(c) for c in v)
    return (f"eye={vec(camera['eye'])}&target={vec(camera['target'])}&up={vec(camera['up'])}"
            f"&fov={camera['fov']!r}&w={w}&h={h}")


def find_object(server, state):
    """Asks /api/pick over a grid of the page's image (nearest the centre first) for an object.

    Returns (css_x, css_y, object), an object with a name and bounds (not a merged pipeline run,
    which answers with its pipeline's id alone). Positions are whole CSS pixels, mapped to image
    pixels the way the page maps a click, so that clicking there picks with the same pixel."""
    w, h = state["natural"]
    left, top, width, height = state["rect"]
    columns, rows = 9, 7
    points = [(left + width * (i + 0.5) / columns, top + height * (j + 0.5) / rows)
              for i in range(columns) for j in range(rows)]
    points.sort(key=lambda p: (p[0] - left - width / 2) ** 2 + (p[1] - top - height / 2) ** 2)
    for css_x, css_y in points:
        css_x, css_y = int(css_x), int(css_y)
        x = min(w - 1, int((css_x - left) * w / width))
        y = min(h - 1, int((css_y - top) * h / height))
        url = f"{server}/api/pick?{camera_query(state['camera'], w, h)}&x={x}&y={y}"
        status, reply = http_json(url, timeout=PICK_S, token=TOKEN)
        if status != 200 or not isinstance(reply, dict) or "object" not in reply:
            raise Failure(f"GET /api/pick answered {status}: {reply}")
        if reply["object"] and reply["object"].get("name") and reply["object"].get("bounds"):
            return css_x, css_y, reply["object"]
    raise Failure(f"/api/pick found no named object at any of {len(points)} grid positions")


def project(camera, aspect, point):
    """Where point lands in the image of camera (vertical fov, image aspect width / height): x and
    y in 0..1 from the top left, and its depth along the view direction in metres. Written from
    the pinhole model, not from the page's code."""
    sub = lambda a, b: [a[i] - b[i] for i in range(3)]
    dot = lambda a, b: sum(a[i] * b[i] for i in range(3))
    cross = lambda a, b: [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    unit = lambda a: [c / dot(a, a) ** 0.5 for c in a]
    forward = unit(sub(camera["target"], camera["eye"]))
    right = unit(cross(forward, camera["up"]))
    up = cross(right, forward)
    v = sub(point, camera["eye"])
    depth = dot(v, forward)
    half_height = depth * math.tan(math.radians(camera["fov"]) / 2)
    return (0.5 + 0.5 * dot(v, right) / (half_height * aspect), 0.5 - 0.5 * dot(v, up) / half_height, depth)


def server_reports_quality(server):
    """Whether the server's frames say what quality they have (X-Plantview-Mode): a small still
    asked for with mode=still (a server from before that refuses the parameter: 400)."""
    try:
        request = urllib.request.Request(f"{server}/api/frame?w=64&h=36&mode=still",
                                         headers={"Authorization": f"Bearer {TOKEN}"})
        with urllib.request.urlopen(request, timeout=FRAME_S) as response:
            return response.headers.get("X-Plantview-Mode") == "still"
    except urllib.error.HTTPError as e:
        if e.code == 400:
            return False
        raise Failure(f"GET /api/frame?w=64&h=36&mode=still answered {e.code}: {e.read()[:200]!r}")


def search_name(server, obj):
    """What a user would type to find obj, and whether it is a tag: where the server finds objects
    by tag (an unknown tag is a 404 there), the first of obj's Tag attribute, its name without the
    leading '/' that plant names carry, and its name, that the server finds as obj. A server that
    finds objects by id only (an unknown tag is a 400) gets the id, and the test says so."""
    status, reply = http_json(f"{server}/api/objects/NO-SUCH-TAG-0000", timeout=PICK_S, token=TOKEN)
    if status == 400:
        print(f"NOTE: this server finds objects by id only ({reply}); searching by id", flush=True)
        return obj["id"], False
    if status != 404:
        raise Failure(f"GET /api/objects/NO-SUCH-TAG-0000 answered {status}: {reply}")
    tags = [a["value"] for a in obj.get("attributes", []) if a.get("key") == "Tag"]
    candidates = tags + [obj["name"].lstrip("/"), obj["name"]]
    for text in candidates:
        path = "/".join(urllib.parse.quote(part, safe="") for part in text.split("/"))
        status, found = http_json(f"{server}/api/objects/{path}", timeout=PICK_S, token=TOKEN)
        if status == 200 and isinstance(found, dict) and found.get("id") == obj["id"]:
            return text, True
    raise Failure(f"the server finds objects by tag, but object {obj['id']} by none of {candidates}")


def search_for(driver, server, state, wait_state, obj):
    """Types the tag (or id) of obj into the search field; checks that the page shows obj's
    attributes, draws its box and flies the camera to frame it, and says which quality it shows."""
    bounds = obj.get("bounds")
    if not bounds:
        raise Failure(f"object {obj.get('id')} has no bounds to fly to: {obj}")
    text, by_tag = search_name(server, obj)
    # Clear the selection (Esc) so that the search, not the earlier click, must select it.
    driver.command("POST", "/actions", {"actions": [{"type": "key", "id": "keyboard", "actions": [
        {"type": "keyDown", "value": "\ue00c"}, {"type": "keyUp", "value": "\ue00c"}]}]})
    before = wait_state("the selection to clear", PICK_S, lambda s: s["selected"] is None)

    # Typed key by key: letters of the tag (W, A, S, D, Q, E...) must not walk the camera.
    driver.type_into("#search-text", text)
    typed = state()
    if typed["camera"] != before["camera"]:
        raise Failure(f"typing {text!r} into the search field moved the camera")
    driver.type_into("#search-text", ENTER_KEY)
    found = wait_state(f"the search for {text!r} to fly to it and show its still", SEARCH_S + FRAME_S,
                       lambda s: s["lastPick"] is not None and s["lastPick"].get("id") == obj["id"]
                       and not s["flying"] and s["still"] and s["framesShown"] > before["framesShown"])
    if obj["name"] not in found["pick"]:
        raise Failure(f"the attributes panel does not show {obj['name']!r}: {found['pick']!r}")
    if not found["selected"] or found["selected"].get("id") != obj["id"]:
        raise Failure(f"the search did not select {obj['id']}: {found['selected']}")

    # The camera moved to look at the object's centre, and the whole object is in the frame.
    centre = [(lo + hi) / 2 for lo, hi in zip(bounds["min"], bounds["max"])]
    cam = found["camera"]
    if cam == before["camera"]:
        raise Failure("the search did not move the camera")
    if max(abs(a - b) for a, b in zip(cam["target"], centre)) > 1e-6:
        raise Failure(f"the camera looks at {cam['target']}, not the object's centre {centre}")
    width, height = found["rect"][2], found["rect"][3]
    corners = [[(bounds["max"] if i >> axis & 1 else bounds["min"])[axis] for axis in range(3)] for i in range(8)]
    for corner in corners:
        x, y, depth = project(cam, width / height, corner)
        if depth <= 0 or not (0 <= x <= 1 and 0 <= y <= 1):
            raise Failure(f"corner {corner} of the object's bounds is outside the frame "
                          f"(x {x:.3f}, y {y:.3f} of 0..1, depth {depth:.3f} m): camera {cam}")
    distance = lambda c: sum((a - b) ** 2 for a, b in zip(c["eye"], c["target"])) ** 0.5

    # The box is drawn, around the middle of the frame (the object is in the middle).
    drawn, middle = driver.js(OVERLAY_PIXELS_JS)
    if drawn == 0 or middle == 0:
        raise Failure(f"the object's box is not drawn around the middle of the frame "
                      f"({drawn} overlay pixels, {middle} in the middle third)")

    # The readout says which quality the still has: as the server reports it, where it does.
    quality = found["quality"] or {}
    if quality.get("mode") != "still" or "quality   still" not in found["stats"]:
        raise Failure(f"the readout does not say the frame is a still: {quality}, {found['stats']!r}")
    if server_reports_quality(server) and (not quality.get("reported") or "reports no quality" in found["stats"]):
        raise Failure(f"the server sends X-Plantview-Mode, but the readout did not read it: {quality}")
    print(f"search {text!r} ({'tag' if by_tag else 'id'}): picked {obj['id']}, camera "
          f"{distance(before['camera']):.1f} m -> {distance(cam):.1f} m from its target, box of "
          f"{drawn} px; readout: {found['stats'].splitlines()[-2].strip()!r}", flush=True)


def run(args, tmp):
    plantview = os.path.abspath(args.plantview)
    store = args.store
    if store:
        store = os.path.abspath(store)
        if not os.path.isdir(store):
            raise Failure(f"--store {store}: not a directory")
    else:
        store = os.path.join(tmp, "store")
        print(f"generating preset a into {store}", flush=True)
        gen = subprocess.run([plantview, "gen", "--preset", "a", "--store", store],
                             capture_output=True, text=True, timeout=600)
        if gen.returncode != 0:
            raise Failure(f"plantview gen failed ({gen.returncode}): {gen.stderr.strip()[-2000:]}")

    processes = {}
    driver = None
    try:
        # 1. The server, until it answers GET /api/model.
        port = args.port or free_port()
        server = f"http://127.0.0.1:{port}"
        server_log = os.path.join(tmp, "server.log")
        processes["server"] = start_process(
            [plantview, "serve", "--store", store, "--listen", f"127.0.0.1:{port}", "--token", TOKEN],
            server_log,
            cwd=REPO_ROOT)

        def server_up():
            if processes["server"].poll() is not None:
                raise Failure(f"plantview serve exited ({processes['server'].returncode}):\n"
                              f"{log_tail(server_log)}")
            try:
                return http_json(f"{server}/api/model", timeout=5, token=TOKEN)[0] == 200
            except OSError:
                return False
        wait_for("GET /api/model to answer 200", SERVER_START_S, server_up)
        print(f"server up at {server}", flush=True)

        # 2. chromedriver and a headless Chromium session.
        driver_port = free_port()
        driver_log = os.path.join(tmp, "chromedriver.log")
        processes["chromedriver"] = start_process([CHROMEDRIVER, f"--port={driver_port}"], driver_log)
        driver = WebDriver(f"http://127.0.0.1:{driver_port}")

        def driver_up():
            if processes["chromedriver"].poll() is not None:
                raise Failure(f"chromedriver exited:\n{log_tail(driver_log)}")
            try:
                status, reply = http_json(f"{driver.base}/status", timeout=5)
                return status == 200 and reply["value"]["ready"]
            except (OSError, KeyError, TypeError):
                return False
        wait_for("chromedriver to be ready", 30, driver_up)
        driver.start(CHROMIUM, ["--headless=new", "--no-sandbox", "--disable-gpu",
                                "--disable-dev-shm-usage",
                                f"--window-size={WINDOW_SIZE[0]},{WINDOW_SIZE[1]}"])

        def state():
            return driver.js(PAGE_STATE_JS)

        def wait_state(what, timeout_s, predicate):
            last = {}
            def probe():
                last["state"] = state()
                return last["state"] if last["state"] and predicate(last["state"]) else None
            try:
                return wait_for(what, timeout_s, probe)
            except Failure as e:
                seen = last.get("state") or {}
                raise Failure(f"{e}; page overlay: {seen.get('stats')!r}") from None

        # 3. The page, until it shows a frame.
        # The server wants its token: the page is given it once, in the fragment.
        if http_json(f"{server}/api/model", timeout=5)[0] != 401:
            raise Failure("the API answered without the token")
        driver.command("POST", "/url", {"url": f"{server}/#token={TOKEN}"})
        first = wait_state("the first frame", FIRST_FRAME_S,
                           lambda s: s["framesShown"] >= 1 and s["natural"][0] > 0 and s["natural"][1] > 0)
        print(f"first frame {first['natural'][0]}x{first['natural'][1]} shown", flush=True)
        if driver.js("return location.hash"):
            raise Failure("the page left its token in the address bar")

        # 4. A drag orbits: the eye moves and a new frame is shown.
        before = wait_state("the still frame", FRAME_S, lambda s: s["still"])
        left, top, width, height = before["rect"]
        cx, cy = left + width / 2, top + height / 2
        driver.pointer([move(cx, cy), {"type": "pointerDown", "button": 0},
                        move(cx + 40, cy + 10, 100), move(cx + 80, cy + 20, 100),
                        move(cx + 120, cy + 30, 100), {"type": "pointerUp", "button": 0}])
        after = state()
        if after["camera"]["eye"] == before["camera"]["eye"]:
            raise Failure(f"the drag did not move the eye: still {after['camera']['eye']}")
        if after["camera"]["target"] != before["camera"]["target"]:
            raise Failure("the orbit moved the target")
        wait_state("a frame after the drag", FRAME_S,
                   lambda s: s["framesShown"] > before["framesShown"])
        print(f"drag moved the eye {before['camera']['eye']} -> {after['camera']['eye']}", flush=True)

        # 5. A click on an object shows its attributes.
        rest = wait_state("the still frame after the drag", FRAME_S, lambda s: s["still"])
        # While the camera moved the page asked for interactive frames (one request at a time, so
        # the first after the drag began is shown), then for one still once it rested.
        modes_before, modes_after = before["framesByMode"], rest["framesByMode"]
        if modes_after["interactive"] <= modes_before["interactive"] or modes_after["still"] <= modes_before["still"]:
            raise Failure(f"frames by mode before the drag {modes_before}, after it came to rest {modes_after}: "
                          "expected interactive frames while it moved and a still at rest")
        css_x, css_y, obj = find_object(server, rest)
        print(f"object {obj.get('id')} {obj.get('name')!r} at ({css_x}, {css_y})", flush=True)
        driver.pointer([move(css_x, css_y), {"type": "pointerDown", "button": 0},
                        {"type": "pointerUp", "button": 0}])
        expected = obj.get("name") or "(unnamed)"
        picked = wait_state(f"#pick to show {expected!r}", PICK_S,
                            lambda s: expected in s["pick"] and s["lastPick"] is not None)
        if picked["lastPick"].get("id") != obj.get("id"):
            raise Failure(f"the page picked {picked['lastPick'].get('id')}, /api/pick said {obj.get('id')}")
        if picked["camera"] != rest["camera"]:
            raise Failure("the click moved the camera")

        # 6. Search: type a tag, see the object picked, boxed and flown to.
        search_for(driver, server, state, wait_state, obj)
        driver.screenshot(args.screenshot)
        print(f"screenshot: {os.path.abspath(args.screenshot)}", flush=True)

        # 7. Home flies back to the model's camera, exactly.
        before_home = state()
        driver.click("#home")
        home = wait_state("the home view's still", FRAME_S + SEARCH_S,
                          lambda s: not s["flying"] and s["still"] and s["framesShown"] > before_home["framesShown"])
        if home["camera"] != home["home"]:
            raise Failure(f"Home ended at {home['camera']}, not the home camera {home['home']}")
        print("home: back at the model's camera", flush=True)
    except Failure:
        if driver and driver.session:
            try:  # what the page looked like, for the failure report
                driver.screenshot(args.screenshot)
                print(f"screenshot of the failure: {os.path.abspath(args.screenshot)}", file=sys.stderr)
            except (Failure, OSError):
                pass
        if "server" in processes:
            print(f"server log (last lines):\n{log_tail(os.path.join(tmp, 'server.log'))}", file=sys.stderr)
        raise
    finally:
        if driver:
            driver.quit()
        stop_process(processes.get("chromedriver"))
        stop_process(processes.get("server"))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plantview", required=True, help="the built plantview binary")
    parser.add_argument("--store", help="store to serve (default: `plantview gen --preset a` into a temporary one)")
    parser.add_argument("--screenshot", default=os.path.join("build", "browser", "viewer.png"),
                        help="where to write the screenshot (default build/browser/viewer.png)")
    parser.add_argument("--port", type=int, default=0, help="server port (0: a free one)")
    args = parser.parse_args()

    for tool in (CHROMIUM, CHROMEDRIVER):
        if not os.access(tool, os.X_OK):
            print(f"SKIP: {tool} is missing (apt-get install chromium chromium-driver)")
            return 77
    if not os.access(args.plantview, os.X_OK):
        print(f"FAIL: --plantview {args.plantview} is not an executable", file=sys.stderr)
        return 1

    tmp = tempfile.mkdtemp(prefix="plantview-browser-")
    try:
        run(args, tmp)
    except Failure as e:
        print(f"FAIL: {e}", file=sys.stderr)
        return 1
    except Exception as e:  # anything unforeseen is a failure too, with its traceback
        import traceback
        traceback.print_exc()
        print(f"FAIL: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
