#!/usr/bin/env python3
"""Browser test of the viewer page (web/) against a running `plantview serve`.

Starts the server on a store, drives headless Chromium through chromedriver (the W3C WebDriver
protocol, JSON over HTTP, spoken here with urllib: no Selenium, standard library only), and checks
that the page shows a frame, orbits on a drag (with interactive frames, then a still at rest),
shows the picked object's attributes on a click, finds an object by the tag typed into its search
field (the attributes panel shows it, its box is drawn over the frame, and the camera flies to
frame it), says which quality the frame has (as the server reports it, where it does), and flies
back to the model's camera on Home. Leaves a screenshot of the page with the found object.

Then the review tools: a section box (its top face dragged down: the frame request carries box=
and the image changes), a BCF viewpoint saved (the downloaded .bcf
unzips and its XML holds the camera, the box as six planes and the selection), the permalink
opened in a fresh window (the same request and the same pixels), and on a second store of two
boxes 1.25 m apart two picked points and the clearance measured through /api/measure (exact to
1 mm). Last, the plant is generated again (another seed) into the served store: the page says
"model updated: revision N, M objects changed" and draws the new revision.

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
import re
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

    def start(self, chromium, args, prefs=None):
        options = {"binary": chromium, "args": args}
        if prefs:
            options["prefs"] = prefs
        capabilities = {"alwaysMatch": {"browserName": "chrome", "goog:chromeOptions": options}}
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
        pick: document.getElementById('pick').innerText,
        frameParams: p.frameParams, section: p.section, sectionHandles: p.sectionHandles,
        measure: p.measure, permalink: p.permalink, picksAnswered: p.picksAnswered, legend: p.legend, style: p.style, lastBcf: p.lastBcf ? {name: p.lastBcf.name, size: p.lastBcf.size} : null,
        error: document.getElementById('stats-error').innerText,
        stream: p.stream ? {...p.stream} : null};
"""

# The displayed frame scaled to 64 x 48, grey levels 0..255 (to compare two pages' images).
FRAME_SIGNATURE_JS = """
const f = document.getElementById('frame');
const c = document.createElement('canvas');
c.width = 64; c.height = 48;
const g = c.getContext('2d');
g.drawImage(f, 0, 0, 64, 48);
const d = g.getImageData(0, 0, 64, 48).data;
const out = [];
for (let i = 0; i < d.length; i += 4) out.push(Math.round((d[i] + d[i + 1] + d[i + 2]) / 3));
return out;
"""

GAP_M = 1.25  # between the two boxes of the measure store

# Two 2 m boxes on the x axis, 1.25 m apart (faces at x = 1 and x = 2.25), in plantview XML.
TWO_BOXES_XML = """<?xml version="1.0" encoding="UTF-8"?>
<plantview format_version="1">
  <object id="00000000000000a1" name="/BOX-A" class="equipment" colour="#3070c0ff" origin_m="0 0 1" source="two_boxes">
    <primitive kind="box" size_x_m="2" size_y_m="2" size_z_m="2" linear="1 0 0 0 1 0 0 0 1" translation_m="0 0 0"/>
  </object>
  <object id="00000000000000b2" name="/BOX-B" class="equipment" colour="#c07030ff" origin_m="3.25 0 1" source="two_boxes">
    <primitive kind="box" size_x_m="2" size_y_m="2" size_z_m="2" linear="1 0 0 0 1 0 0 0 1" translation_m="0 0 0"/>
  </object>
</plantview>
"""


def mean_difference(a, b):
    return sum(abs(x - y) for x, y in zip(a, b)) / max(1, len(a))

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


def wait_download(directory, timeout_s):
    """The first finished .bcf file in directory, or None after timeout_s."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        done = [n for n in os.listdir(directory) if n.endswith(".bcf")]
        if done:
            return os.path.join(directory, done[0])
        time.sleep(0.25)
    return None


def check_bcf(path_or_bytes, title, camera, box, component):
    """The saved viewpoint unzips (CRCs right) and its XML says what the page showed."""
    import io
    import xml.etree.ElementTree as ET
    import zipfile
    source = io.BytesIO(path_or_bytes) if isinstance(path_or_bytes, bytes) else path_or_bytes
    with zipfile.ZipFile(source) as z:
        bad = z.testzip()
        if bad:
            raise Failure(f"the .bcf's entry {bad} fails its CRC")
        names = z.namelist()
        if "bcf.version" not in names:
            raise Failure(f"the .bcf has no bcf.version: {names}")
        version = ET.fromstring(z.read("bcf.version"))
        if version.get("VersionId") != "2.1":
            raise Failure(f"bcf.version says {version.attrib}, not 2.1")
        topics = {n.split("/")[0] for n in names if "/" in n}
        if len(topics) != 1:
            raise Failure(f"expected one topic folder, got {sorted(topics)}")
        topic = topics.pop()
        markup = ET.fromstring(z.read(f"{topic}/markup.bcf"))
        if markup.find("Topic").get("Guid") != topic or markup.findtext("Topic/Title") != title:
            raise Failure(f"markup.bcf: topic {markup.find('Topic').attrib}, title {markup.findtext('Topic/Title')!r}")
        if not markup.findtext("Topic/CreationDate"):
            raise Failure("markup.bcf has no CreationDate")
        vp = ET.fromstring(z.read(f"{topic}/viewpoint.bcfv"))
        xyz = lambda e: [float(e.findtext(k)) for k in ("X", "Y", "Z")]
        eye = xyz(vp.find("PerspectiveCamera/CameraViewPoint"))
        direction = xyz(vp.find("PerspectiveCamera/CameraDirection"))
        fov = float(vp.findtext("PerspectiveCamera/FieldOfView"))
        forward = [t - e for t, e in zip(camera["target"], camera["eye"])]
        norm = sum(c * c for c in forward) ** 0.5
        if max(abs(a - b) for a, b in zip(eye, camera["eye"])) > 1e-9 or abs(fov - camera["fov"]) > 1e-9 or \
                max(abs(a - b / norm) for a, b in zip(direction, forward)) > 1e-9:
            raise Failure(f"viewpoint.bcfv camera {eye} {direction} {fov}, the page's {camera}")
        planes = [(xyz(p.find("Location")), xyz(p.find("Direction"))) for p in vp.findall("ClippingPlanes/ClippingPlane")]
        if len(planes) != 6:
            raise Failure(f"the section box should be six clipping planes, got {len(planes)}")
        top = [loc for loc, d in planes if d == [0.0, 0.0, 1.0]]
        if len(top) != 1 or abs(top[0][2] - box["max"][2]) > 1e-9:
            raise Failure(f"no clipping plane at the box's top {box['max'][2]} pointing up (into the removed side): {planes}")
        ids = [c.findtext("AuthoringToolId") for c in vp.findall("Components/Selection/Component")]
        systems = [c.findtext("OriginatingSystem") for c in vp.findall("Components/Selection/Component")]
        if ids != [component] or systems != ["plantview"]:
            raise Failure(f"the selection's components are {ids} from {systems}, expected [{component!r}]")
        snapshot = z.read(f"{topic}/snapshot.png") if f"{topic}/snapshot.png" in names else b""
        if not snapshot.startswith(b"\x89PNG"):
            raise Failure("the .bcf has no PNG snapshot")
        validate_bcf_xml({"version.xsd": z.read("bcf.version"), "markup.xsd": z.read(f"{topic}/markup.bcf"),
                          "visinfo.xsd": z.read(f"{topic}/viewpoint.bcfv")})
        return len(names), len(snapshot)


def validate_bcf_xml(documents):
    """Each document against its BCF 2.1 schema (tests/data/bcf/*.xsd) with xmllint, where both
    are there; else a NOTE."""
    schemas = os.path.join(REPO_ROOT, "tests", "data", "bcf")
    xmllint = shutil.which("xmllint")
    if not all(os.path.exists(os.path.join(schemas, x)) for x in documents):
        raise Failure(f"the BCF 2.1 schemas are missing from {schemas}")
    if not xmllint:
        print("NOTE: no xmllint (libxml2-utils, scripts/deps.sh): the BCF XML is not validated", flush=True)
        return
    for xsd, text in documents.items():
        checked = subprocess.run([xmllint, "--noout", "--schema", os.path.join(schemas, xsd), "-"],
                                 input=text, capture_output=True, timeout=60)
        if checked.returncode != 0:
            raise Failure(f"the viewpoint's XML fails {xsd}: {checked.stderr.decode(errors='replace')[-1000:]}")


def review_tools(driver, server, state, wait_state, obj, text, downloads, tmp, screenshot):
    """Section box (a face dragged), BCF viewpoint saved, permalink opened in a fresh window."""
    # The object selected again (search flies to it); its box is what the section box surrounds.
    driver.command("POST", "/actions", {"actions": [{"type": "key", "id": "keyboard", "actions": [
        {"type": "keyDown", "value": "\ue00c"}, {"type": "keyUp", "value": "\ue00c"}]}]})  # Esc
    wait_state("the selection to clear", PICK_S, lambda s: s["selected"] is None)
    driver.command("POST", f"/element/{driver.element('#search-text')}/clear", {})
    driver.type_into("#search-text", text + ENTER_KEY)
    found = wait_state("the search to show its still again", SEARCH_S + FRAME_S,
                       lambda s: s["selected"] and s["selected"].get("id") == obj["id"] and not s["flying"] and s["still"])
    before = driver.js(FRAME_SIGNATURE_JS)

    # 8. Section box: around the selection, its top face (handle 5) dragged half way down.
    driver.click("#section-tool > summary")
    driver.click("#section-box")
    boxed = wait_state("a still with the section box and its six handles", FRAME_S,
                       lambda s: s["still"] and s["section"] and s["section"]["box"]
                       and "box=" in (s["frameParams"] or "") and len(s["sectionHandles"]) == 6)
    box0 = boxed["section"]["box"]
    handles = {h["face"]: h for h in boxed["sectionHandles"]}
    top, bottom = handles[5], handles[4]
    if math.hypot(top["x"] - bottom["x"], top["y"] - bottom["y"]) < 20:
        raise Failure(f"the box's top and bottom handles are drawn too close to drag: {top}, {bottom}")
    tx, ty = (top["x"] + bottom["x"]) / 2, (top["y"] + bottom["y"]) / 2
    driver.pointer([move(top["x"], top["y"]), {"type": "pointerDown", "button": 0},
                    move((top["x"] + tx) / 2, (top["y"] + ty) / 2, 100), move(tx, ty, 100),
                    {"type": "pointerUp", "button": 0}])
    cut = wait_state("a still of the cut box", FRAME_S,
                     lambda s: s["still"] and s["section"]["box"]["max"][2] < box0["max"][2] - 1e-3
                     and "box=" in s["frameParams"] and s["frameParams"] != boxed["frameParams"])
    box = cut["section"]["box"]
    if cut["camera"] != boxed["camera"]:
        raise Failure("dragging a face of the section box moved the camera")
    if box["min"] != box0["min"] or box["max"][:2] != box0["max"][:2]:
        raise Failure(f"dragging the top face moved other faces: {box0} -> {box}")
    after = driver.js(FRAME_SIGNATURE_JS)
    change = mean_difference(before, after)
    driver.screenshot(screenshot)
    if change < 1.0:
        raise Failure(f"the section box cut nothing: the image changed by {change:.2f} grey levels")
    print(f"section box: top {box0['max'][2]:.3f} -> {box['max'][2]:.3f} m, image changed by {change:.1f}", flush=True)

    # Colour by an attribute every object of preset a has, and the selection highlighted.
    driver.click("#style-tool > summary")
    driver.type_into("#colour-by", "Type")
    driver.click("#style-form button[type=submit]")
    driver.click("#isolate")
    styled = wait_state("a still coloured by Type with the selection highlighted", FRAME_S,
                        lambda s: s["still"] and "colour_by=Type" in s["frameParams"]
                        and f"highlight={obj['id']}" in s["frameParams"] and "box=" in s["frameParams"])
    if styled["legend"]:
        if styled["legend"].get("key") != "Type" or not driver.js("return !document.getElementById('legend').hidden"):
            raise Failure(f"the legend panel does not show the frame's legend: {styled['legend']}")
        print(f"colour by Type: legend of {len(styled['legend'].get('entries', []))} entries shown", flush=True)
    else:
        raise Failure("a frame coloured by Type came without its legend (X-Plantview-Legend)")

    # 9. Save the viewpoint: a BCF 2.1 zip downloaded, its XML as the page showed it.
    driver.click("#viewpoint-tool > summary")
    title = "Valve check <A&B>"
    driver.type_into("#bcf-title", title)
    driver.click("#bcf-save")
    saved = wait_state("the viewpoint to be saved", FRAME_S, lambda s: s["lastBcf"] is not None)
    path = wait_download(downloads, 20)
    if path:
        source = path
    else:
        print("NOTE: no download arrived in headless Chromium; checking the page's copy of the file", flush=True)
        source = os.path.join(tmp, "viewpoint.bcf")
        with open(source, "wb") as f:
            f.write(base64.b64decode(driver.js("return window.plantview.lastBcf.base64")))
    entries, png_bytes = check_bcf(source, title, saved["camera"], box, obj["name"].lstrip("/"))
    print(f"viewpoint: {saved['lastBcf']['name']} ({saved['lastBcf']['size']} bytes, {entries} entries, "
          f"snapshot {png_bytes} bytes) parses as BCF 2.1", flush=True)

    # 10. The permalink in a fresh window: the same request, the same image.
    link = saved["permalink"]
    if not link or any(part not in link for part in ("box=", f"sel={obj['id']}", "colour_by=Type", "hl=1")):
        raise Failure(f"the permalink does not hold the section box, the selection and the styling: {link}")
    first_window = driver.command("GET", "/window")
    rect = driver.command("GET", "/window/rect")
    # The image compared is this window's still of the saved request (opening the viewpoint
    # panel may have asked for another frame, and a late interactive frame is not the still).
    wait_state("the still of the saved viewpoint", FRAME_S,
               lambda s: s["still"] and s["frameParams"] == saved["frameParams"])
    pixels = driver.js(FRAME_SIGNATURE_JS)
    handle = driver.command("POST", "/window/new", {"type": "window"})["handle"]
    driver.command("POST", "/window", {"handle": handle})
    driver.command("POST", "/window/rect", {"width": rect["width"], "height": rect["height"]})
    driver.command("POST", "/url", {"url": f"{link}&token={TOKEN}"})
    fresh = wait_state("the permalink's still", FIRST_FRAME_S + FRAME_S,
                       lambda s: s["still"] and s["frameParams"] is not None)
    if fresh["frameParams"] != saved["frameParams"]:
        raise Failure(f"the permalink asks for\n  {fresh['frameParams']}\nnot\n  {saved['frameParams']}")
    # The same still, once it is on screen: a frame shown just before it (the stream's, on a
    # loaded machine) may stand for a moment; a different image stays different.
    deadline = time.monotonic() + 10
    while True:
        difference = mean_difference(pixels, driver.js(FRAME_SIGNATURE_JS))
        if difference <= 0.5 or time.monotonic() > deadline:
            break
        time.sleep(0.25)
    if difference > 0.5:
        raise Failure(f"the permalink's image differs by {difference:.2f} grey levels on average")
    if not fresh["selected"] or fresh["selected"].get("id") != obj["id"]:
        raise Failure(f"the permalink did not restore the selection: {fresh['selected']}")
    print(f"permalink: same request and image (mean difference {difference:.2f}) in a fresh window", flush=True)

    # The saved viewpoint opened after going home without a box: camera, box and selection back.
    driver.command("POST", "/actions", {"actions": [{"type": "key", "id": "keyboard", "actions": [
        {"type": "keyDown", "value": "\ue00c"}, {"type": "keyUp", "value": "\ue00c"}]}]})  # Esc
    if not driver.js("return document.getElementById('section-tool').open"):
        driver.click("#section-tool > summary")
    driver.click("#section-reset")
    driver.click("#home")
    wait_state("home without a box", FRAME_S + SEARCH_S,
               lambda s: not s["flying"] and s["still"] and s["camera"] == s["home"] and not s["section"]["box"])
    driver.command("POST", f"/element/{driver.element('#bcf-open')}/value", {"text": os.path.abspath(source)})
    opened = wait_state("the opened viewpoint's still", FRAME_S,
                        lambda s: s["still"] and s["section"]["box"] and s["selected"] is not None)
    eye_error = max(abs(a - b) for a, b in zip(opened["camera"]["eye"], saved["camera"]["eye"]))
    if eye_error > 1e-9 or opened["camera"]["fov"] != saved["camera"]["fov"]:
        raise Failure(f"the opened viewpoint's camera {opened['camera']}, the saved one {saved['camera']}")
    if opened["section"]["box"] != box or opened["selected"].get("id") != obj["id"]:
        raise Failure(f"the opened viewpoint: box {opened['section']['box']} (saved {box}), "
                      f"selection {opened['selected'].get('id')} (saved {obj['id']})")
    print("viewpoint opened: camera, section box and selection restored", flush=True)
    driver.command("DELETE", "/window")
    driver.command("POST", "/window", {"handle": first_window})


def measure_two_boxes(driver, plantview, tmp, processes, wait_state):
    """Two boxes GAP_M apart: clearance mode, a click on each, the distance from /api/measure."""
    xml_path = os.path.join(tmp, "two_boxes.xml")
    with open(xml_path, "w") as f:
        f.write(TWO_BOXES_XML)
    store = os.path.join(tmp, "two_boxes")
    made = subprocess.run([plantview, "import", xml_path, "--store", store], capture_output=True, text=True, timeout=120)
    if made.returncode != 0:
        raise Failure(f"plantview import of the two boxes failed: {made.stderr.strip()[-1000:]}")
    port = free_port()
    server = f"http://127.0.0.1:{port}"
    log = os.path.join(tmp, "server2.log")
    processes["server2"] = start_process([plantview, "serve", "--store", store, "--listen", f"127.0.0.1:{port}",
                                          "--token", TOKEN], log, cwd=REPO_ROOT)
    try:
        def up():
            if processes["server2"].poll() is not None:
                raise Failure(f"the second server exited:\n{log_tail(log)}")
            try:
                return http_json(f"{server}/api/model", timeout=5, token=TOKEN)[0] == 200
            except OSError:
                return False
        wait_for("the two boxes' server", SERVER_START_S, up)
        # Opened on a view of the two from the side (a permalink's camera): both faces in sight.
        driver.command("POST", "/url", {"url": f"{server}/#eye=1.625,-12,1&target=1.625,0,1&up=0,0,1&fov=50&token={TOKEN}"})
        shown = wait_state("the two boxes' still", FIRST_FRAME_S, lambda s: s["still"] and s["natural"][0] > 0)
        if shown["camera"]["eye"] != [1.625, -12, 1]:
            raise Failure(f"the page did not open at the link's camera: {shown['camera']}")
        driver.click("#measure-tool > summary")
        left, top, width, height = shown["rect"]
        clicks = []
        for centre, name in (([0, 0, 1], "/BOX-A"), ([3.25, 0, 1], "/BOX-B")):
            x, y, depth = project(shown["camera"], width / height, centre)
            if depth <= 0 or not (0 < x < 1 and 0 < y < 1):
                raise Failure(f"{name}'s centre is not in the view: {x:.3f}, {y:.3f}")
            css_x, css_y = int(left + x * width), int(top + y * height)
            w, h = shown["natural"]
            px, py = min(w - 1, int((css_x - left) * w / width)), min(h - 1, int((css_y - top) * h / height))
            status, reply = http_json(f"{server}/api/pick?{camera_query(shown['camera'], w, h)}&x={px}&y={py}",
                                      timeout=PICK_S, token=TOKEN)
            if status != 200 or not (reply.get("object") or {}).get("name") == name:
                raise Failure(f"the pixel of {name}'s centre picks {status} {reply}")
            clicks.append((css_x, css_y, name))
        def click_both():
            # Each pick answered before the next click (a newer pick drops an older one's answer).
            for cx, cy, name in clicks:
                answered = driver.js("return window.plantview.picksAnswered")
                driver.pointer([move(cx, cy), {"type": "pointerDown", "button": 0}, {"type": "pointerUp", "button": 0}])
                wait_state(f"the pick of {name}", PICK_S, lambda s: s["picksAnswered"] > answered)
            return wait_state("the measurement or its error", PICK_S + FRAME_S,
                              lambda s: s["measure"] is not None or "measure" in s["error"])

        # Point to point: the two front faces (y = -1) where the rays through the boxes' centres meet them.
        driver.click('input[name="measure-mode"][value="points"]')
        done = click_both()
        if done["measure"] is None:
            raise Failure(f"measuring two points failed: {done['error']!r}")
        else:
            m = done["measure"]
            # The rays through the two centres meet the faces at y = -1, 11 m of the eye's 12 m to the
            # centres' plane: in perspective the two points are 3.25 * 11 / 12 m apart in x.
            eye_y = shown["camera"]["eye"][1]
            expected_dx = 3.25 * (-1 - eye_y) / (0 - eye_y)
            if any(abs(p[1] + 1) > 1e-3 for p in (m["a"], m["b"])) or abs(m["dx_m"] - expected_dx) > 0.05:
                raise Failure(f"the points picked on the two front faces: {m}")
            print(f"measure: points {m['distance_m']:.3f} m apart (dx {m['dx_m']:.3f})", flush=True)
        driver.js("document.getElementById('stats-error').textContent = ''")

        # Clearance: the two objects, their closest points and distance from /api/measure.
        driver.click('input[name="measure-mode"][value="objects"]')
        done = click_both()
        if done["measure"] is None:
            raise Failure(f"measuring the two boxes failed: {done['error']!r}")
        m = done["measure"]
        if abs(m["distance_m"] - GAP_M) > 1e-3 or abs(abs(m["dx_m"]) - GAP_M) > 1e-3:
            raise Failure(f"the boxes are {GAP_M} m apart, the page measured {m}")
        print(f"measure: clearance {m['distance_m']:.4f} m (expected {GAP_M})", flush=True)
    finally:
        stop_process(processes.pop("server2", None))


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
        downloads = os.path.join(tmp, "downloads")
        os.makedirs(downloads)
        driver.start(CHROMIUM, ["--headless=new", "--no-sandbox", "--disable-gpu",
                                "--disable-dev-shm-usage",
                                f"--window-size={WINDOW_SIZE[0]},{WINDOW_SIZE[1]}"],
                     prefs={"download.default_directory": downloads, "download.prompt_for_download": False})

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
        if "token=" in driver.js("return location.hash"):
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

        # 4b. Those frames came over the stream (/api/stream), as video where this Chromium
        # decodes it (WebCodecs), else JPEG, and followed the camera: the frame at rest is the
        # dragged camera's, and more frames came from the stream during the drag.
        moved = wait_state("the dragged camera's frame from the stream", FRAME_S,
                           lambda s: s["still"] and s["stream"] and s["stream"]["transport"] == "stream")
        streamed_before, streamed = (before.get("stream") or {}), moved["stream"]
        if streamed["fellBack"] != 0:
            raise Failure(f"the stream closed or did not open ({streamed['fellBack']} times): {streamed}")
        if streamed["codec"] not in ("jpeg", "h264", "vp8"):
            raise Failure(f"the stream's codec is {streamed['codec']!r}")
        if streamed["frames"] < streamed_before.get("frames", 0) + 2:
            raise Failure(f"the stream showed {streamed['frames']} frames, {streamed_before.get('frames')} before the drag")
        video = driver.js("return 'VideoDecoder' in window")
        if streamed["codec"] != "jpeg" and streamed["videoFrames"] < 1:
            raise Failure(f"the stream is {streamed['codec']} but no video frame was decoded: {streamed}")
        if not re.search(r"transport stream · (jpeg|h264|vp8) · ", moved["stats"]):
            raise Failure(f"the readout does not say the stream, codec and rate: {moved['stats']!r}")
        print(f"stream: {streamed['codec']} (WebCodecs {'present' if video else 'absent'}), "
              f"{streamed['frames']} frames, {streamed['videoFrames']} video, latency "
              f"{streamed['latencyMs']:.0f} ms", flush=True)

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

        # 8-10. Section box, BCF viewpoint, permalink.
        text, _ = search_name(server, obj)
        review_tools(driver, server, state, wait_state, obj, text, downloads, tmp,
                     args.screenshot.replace(".png", "-section.png"))

        # 12. The server follows an import into its store (only into a store of this test's own):
        # the page notices the new revision, says what changed, and draws it.
        if not args.store:
            before_import = state()
            revision = driver.js("return window.plantview.revision")
            gen = subprocess.run([plantview, "gen", "--preset", "a", "--seed", "2", "--store", store],
                                 capture_output=True, text=True, timeout=600)
            if gen.returncode != 0:
                raise Failure(f"plantview gen --seed 2 failed ({gen.returncode}): {gen.stderr.strip()[-2000:]}")
            # An idle page hears of it from its poll of /api/model (every 5 s).
            def updated():
                text = driver.js("const e = document.getElementById('model-updated');"
                                 "return e && !e.hidden ? e.textContent : null")
                return text if text and driver.js("return window.plantview.revision") > revision else None
            text = wait_for("the page to say the model was updated", 5 + FRAME_S, updated)
            if not text.startswith(f"model updated: revision {revision + 1}, ") or "changed" not in text:
                raise Failure(f"the update bar says {text!r}")
            wait_state("a frame of the new revision", FRAME_S,
                       lambda s: s["framesShown"] > before_import["framesShown"])
            print(f"follow: {text}", flush=True)

        # 11. Measure the clearance of two boxes a known gap apart, on a store of their own.
        measure_two_boxes(driver, plantview, tmp, processes, wait_state)
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
