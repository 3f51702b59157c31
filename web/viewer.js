// plantview viewer. Every frame is rendered by `plantview serve`; this page only moves a camera,
// asks for images of it and shows them.
//
// Camera conventions: model space in metres, z up. eye, target and up are [x, y, z] arrays of
// doubles (plants sit at large coordinates: never round them); fov is the vertical field of view
// in degrees, and the image's aspect ratio is that of the w×h requested. The model's camera is used
// as given until the first move; orbiting and walking then keep up = +z.
//
// Test hooks (tests/browser/test_viewer.py reads them): window.plantview = {
//   camera,       the current camera {eye, target, up, fov} (replaced, never mutated, on a change)
//   framesShown,  frames displayed since the page loaded
//   lastPick,     the object of the last pick ({id, name, class, attributes, bounds}) or null
//   still,        true while the displayed frame is the full-quality still of the current camera
// }
'use strict';

(() => {
  const MOVING = { quality: 50, px: 3 };   // while the camera moves: cheap, coarse frames
  const STILL = { quality: 90, px: 1 };    // once it has rested REST_MS: one full-quality still
  const REST_MS = 250;
  const CLICK_SLOP_PX = 4;                 // a press that moves at most this far is a click (a pick)
  const MAX_SIDE_PX = 4096;                // the server's limit on w and h
  const ORBIT_RAD_PER_PX = 0.005;
  const ELEVATION_LIMIT_RAD = 89 * Math.PI / 180;  // orbit never flips over the poles
  const MIN_DISTANCE_M = 0.1;              // zoom stops this close to the target
  const Z_UP = [0, 0, 1];

  const frame = document.getElementById('frame');
  const statsLines = document.getElementById('stats-lines');
  const statsError = document.getElementById('stats-error');
  const pickPanel = document.getElementById('pick');

  const hooks = { camera: null, framesShown: 0, lastPick: null, still: false };
  window.plantview = hooks;

  // Identifies this page load to the server, which answers an older waiting request of the same
  // client 409 when a newer one arrives.
  const clientId = Array.from(crypto.getRandomValues(new Uint32Array(2)), (n) => n.toString(16)).join('');

  let model = null;           // GET /api/model
  let camera = null;          // the current camera; replaced only by setCamera()
  let shown = null;           // what the displayed frame was rendered with: {params, w, h, still}
  let shownUrl = null;        // object URL of the displayed frame (revoked when replaced)
  let inFlight = false;       // at most one frame request is outstanding
  let lastChangeMs = -Infinity;  // performance.now() of the last camera or size change
  let blockedUntilMs = 0;     // after a 503 or a network error: no frame request before this
  let failedParams = null;    // a request the server refused: not repeated until something changes
  let pumpTimer = 0;
  let pickSeq = 0;            // only the answer to the latest pick is shown
  const shownTimesMs = [];    // display times of the recent frames, for the achieved rate

  // ---- vectors ([x, y, z] arrays) ----
  const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const length = (a) => Math.sqrt(dot(a, a));
  const normalize = (a) => { const l = length(a); return l > 0 ? scale(a, 1 / l) : a; };
  const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));

  // The camera's unit forward, right and up vectors (right-handed: right = forward × up).
  function viewBasis(cam) {
    const forward = normalize(sub(cam.target, cam.eye));
    let right = cross(forward, cam.up);
    if (length(right) < 1e-9) right = cross(forward, Math.abs(forward[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0]);
    right = normalize(right);
    return { forward, right, up: cross(right, forward) };
  }

  function setCamera(eye, target, up) {
    camera = { eye, target, up, fov: camera.fov };
    hooks.camera = camera;
    changed();
  }

  // A camera or size change: frames are coarse until REST_MS after the last one.
  function changed() {
    lastChangeMs = performance.now();
    failedParams = null;
    hooks.still = false;
    pump();
  }

  // ---- navigation ----

  // Orbit: turn the eye about the target, around world z (azimuth) and the horizontal axis
  // (elevation). Dragging right turns the scene right; dragging down looks more from above.
  function orbit(dxPx, dyPx) {
    const offset = sub(camera.eye, camera.target);
    const r = length(offset);
    if (r === 0) return;
    const azimuth = Math.atan2(offset[1], offset[0]) - dxPx * ORBIT_RAD_PER_PX;
    const elevation = clamp(Math.asin(clamp(offset[2] / r, -1, 1)) + dyPx * ORBIT_RAD_PER_PX,
                            -ELEVATION_LIMIT_RAD, ELEVATION_LIMIT_RAD);
    const c = Math.cos(elevation);
    const eye = add(camera.target, scale([c * Math.cos(azimuth), c * Math.sin(azimuth), Math.sin(elevation)], r));
    setCamera(eye, camera.target, Z_UP);
  }

  // Pan: move eye and target together in the view plane so that what lies at the target's distance
  // follows the cursor: one CSS pixel there is 2·d·tan(fov/2) / (element height in CSS px) metres.
  function pan(dxPx, dyPx) {
    const { right, up } = viewBasis(camera);
    const d = length(sub(camera.target, camera.eye));
    const metresPerPx = 2 * d * Math.tan(camera.fov * Math.PI / 360) / Math.max(1, frame.clientHeight);
    const move = add(scale(right, -dxPx * metresPerPx), scale(up, dyPx * metresPerPx));
    setCamera(add(camera.eye, move), add(camera.target, move), camera.up);
  }

  // Zoom: scale the eye's distance to the target by a factor per wheel pixel (multiplicative, so
  // each notch feels the same near and far); wheel down moves away.
  function zoom(wheelPx) {
    const offset = sub(camera.eye, camera.target);
    const d = length(offset);
    if (d === 0) return;
    const newD = Math.max(MIN_DISTANCE_M, d * Math.exp(wheelPx * 0.002));
    setCamera(add(camera.target, scale(offset, newD / d)), camera.target, camera.up);
  }

  // Walk: W/S along the horizontal view direction, A/D sideways, Q/E down/up, moving eye and target
  // together. Speed is half the eye–target distance per second (at least 2 m/s), so a walk takes
  // about as long whether one looks at a valve or at the whole plant.
  const held = new Set();
  let walking = false;        // a walkStep is scheduled
  let lastStepMs = 0;
  function walkStep(nowMs) {
    if (held.size === 0 || !camera) { walking = false; lastStepMs = 0; return; }
    const dt = lastStepMs ? Math.min(0.1, (nowMs - lastStepMs) / 1000) : 0;
    lastStepMs = nowMs;
    const { forward, up } = viewBasis(camera);
    // Looking straight down, "ahead" is the top of the screen.
    let ahead = [forward[0], forward[1], 0];
    if (length(ahead) < 1e-6) ahead = [up[0], up[1], 0];
    ahead = normalize(ahead);
    const side = cross(ahead, Z_UP);
    const axis = (plus, minus) => (held.has(plus) ? 1 : 0) - (held.has(minus) ? 1 : 0);
    let dir = add(add(scale(ahead, axis('w', 's')), scale(side, axis('d', 'a'))), scale(Z_UP, axis('e', 'q')));
    const speed = Math.max(2, 0.5 * length(sub(camera.target, camera.eye)));  // m/s
    if (dt > 0 && length(dir) > 0) {
      const move = scale(normalize(dir), speed * dt);
      setCamera(add(camera.eye, move), add(camera.target, move), Z_UP);
    }
    requestAnimationFrame(walkStep);
  }

  window.addEventListener('keydown', (e) => {
    const key = e.key.toLowerCase();
    if (e.ctrlKey || e.metaKey || e.altKey || !'wasdqe'.includes(key) || key.length !== 1) return;
    e.preventDefault();
    held.add(key);
    if (!walking) { walking = true; requestAnimationFrame(walkStep); }
  });
  window.addEventListener('keyup', (e) => held.delete(e.key.toLowerCase()));
  window.addEventListener('blur', () => held.clear());

  // Pointer: a press that moves more than CLICK_SLOP_PX drags (left: orbit; right, middle or
  // shift: pan); one that does not is a click, and a left click picks.
  let drag = null;
  frame.addEventListener('pointerdown', (e) => {
    if (drag || !camera) return;
    e.preventDefault();
    frame.setPointerCapture(e.pointerId);
    drag = { id: e.pointerId, x0: e.clientX, y0: e.clientY, x: e.clientX, y: e.clientY,
             moved: false, pan: e.button !== 0 || e.shiftKey };
  });
  frame.addEventListener('pointermove', (e) => {
    if (!drag || e.pointerId !== drag.id) return;
    if (!drag.moved) {
      if (Math.hypot(e.clientX - drag.x0, e.clientY - drag.y0) <= CLICK_SLOP_PX) return;
      drag.moved = true;
      frame.classList.add('dragging');
    }
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    if (drag.pan) pan(dx, dy); else orbit(dx, dy);
  });
  const endDrag = (e, isClick) => {
    if (!drag || e.pointerId !== drag.id) return;
    if (isClick && !drag.moved && !drag.pan) pick(e.clientX, e.clientY);
    drag = null;
    frame.classList.remove('dragging');
  };
  frame.addEventListener('pointerup', (e) => endDrag(e, true));
  frame.addEventListener('pointercancel', (e) => endDrag(e, false));
  frame.addEventListener('contextmenu', (e) => e.preventDefault());
  frame.addEventListener('wheel', (e) => {
    e.preventDefault();
    if (!camera) return;
    const linePx = e.deltaMode === 1 ? 16 : e.deltaMode === 2 ? window.innerHeight : 1;
    zoom(e.deltaY * linePx);
  }, { passive: false });
  window.addEventListener('resize', () => { if (camera) changed(); });

  // ---- frames ----

  // The image size to request: the element's CSS size × devicePixelRatio, scaled down (keeping the
  // aspect ratio) so that neither side exceeds MAX_SIDE_PX.
  function frameSize() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(frame.clientWidth * dpr));
    const h = Math.max(1, Math.round(frame.clientHeight * dpr));
    const s = Math.min(1, MAX_SIDE_PX / Math.max(w, h));
    return { w: Math.max(1, Math.floor(w * s)), h: Math.max(1, Math.floor(h * s)) };
  }

  // Query parameters for a camera and image size (shared by frame, stats and pick).
  function cameraParams(cam, w, h) {
    return `eye=${cam.eye.join(',')}&target=${cam.target.join(',')}&up=${cam.up.join(',')}` +
           `&fov=${cam.fov}&w=${w}&h=${h}`;
  }

  // The in-flight rule: at most one frame request is outstanding. pump() runs whenever one ends
  // (shown, failed or superseded), the camera or size changes, or the camera comes to rest, and
  // asks for the frame wanted now: the *latest* camera at MOVING quality until it has rested
  // REST_MS, then once at STILL quality. Cameras passed while a request was out are skipped.
  function pump() {
    clearTimeout(pumpTimer);
    if (inFlight || !camera) return;
    const nowMs = performance.now();
    if (nowMs < blockedUntilMs) { pumpTimer = setTimeout(pump, blockedUntilMs - nowMs); return; }
    const restsInMs = lastChangeMs + REST_MS - nowMs;
    const still = restsInMs <= 0;
    if (!still) pumpTimer = setTimeout(pump, restsInMs + 1);  // the still, once it rests
    const { w, h } = frameSize();
    const params = cameraParams(camera, w, h);
    if (shown && shown.params === params && (shown.still || !still)) return;  // already showing it
    if (params === failedParams) return;
    const q = still ? STILL : MOVING;
    inFlight = true;
    const url = `api/frame?${params}&format=jpeg&quality=${q.quality}&lod=screen-space&px=${q.px}` +
                `&client=${clientId}`;
    fetchFrame(url, { params, w, h, still }).finally(() => { inFlight = false; pump(); });
  }

  async function fetchFrame(url, request) {
    try {
      const response = await fetch(url, { cache: 'no-store' });
      if (response.status === 409) return;  // superseded by a newer request of ours: ignore
      if (response.status === 503) {
        const seconds = parseFloat(response.headers.get('Retry-After'));
        const waitMs = 1000 * (Number.isFinite(seconds) && seconds >= 0 ? seconds : 1);
        blockedUntilMs = performance.now() + waitMs;
        showError(`server busy: retrying in ${(waitMs / 1000).toFixed(1)} s`);
        return;
      }
      if (!response.ok) {
        failedParams = request.params;
        showError(`frame: ${await errorText(response)}`);
        return;
      }
      const url2 = URL.createObjectURL(await response.blob());
      frame.src = url2;
      try {
        await frame.decode();
      } catch {
        URL.revokeObjectURL(url2);
        if (shownUrl) frame.src = shownUrl;
        failedParams = request.params;
        showError('frame: the image could not be decoded');
        return;
      }
      if (shownUrl) URL.revokeObjectURL(shownUrl);
      shownUrl = url2;
      shown = request;
      hooks.framesShown += 1;
      const { w, h } = frameSize();
      hooks.still = request.still && request.params === cameraParams(camera, w, h);
      showStats(response.headers, request.still);
      showError('');
    } catch (e) {
      // The network (the server restarting?): try again in a little while.
      blockedUntilMs = performance.now() + 2000;
      showError(`frame: ${e.message}`);
    }
  }

  async function errorText(response) {
    try {
      const body = await response.json();
      if (body && body.error) return `${response.status}: ${body.error}`;
    } catch { /* not JSON */ }
    return `${response.status} ${response.statusText}`;
  }

  function showError(text) { statsError.textContent = text; }

  // The overlay: the displayed frame's statistics (from its response headers) and the frame rate
  // achieved over the last two seconds.
  function showStats(headers, still) {
    const nowMs = performance.now();
    shownTimesMs.push(nowMs);
    while (shownTimesMs.length > 1 && nowMs - shownTimesMs[0] > 2000) shownTimesMs.shift();
    const n = shownTimesMs.length;
    const fps = n > 1 ? (n - 1) * 1000 / (nowMs - shownTimesMs[0]) : null;
    const num = (name) => { const v = parseFloat(headers.get(name)); return Number.isFinite(v) ? v : null; };
    const count = (v) => (v === null ? '–' : v.toLocaleString('en-US'));
    const mb = (v) => (v === null ? '–' : (v / 1048576).toFixed(1));
    const frameMs = num('X-Frame-Ms');
    statsLines.textContent = [
      `triangles ${count(num('X-Triangles'))}`,
      `objects   ${count(num('X-Objects-Visible'))} visible of ${count(model.objects ?? null)}`,
      `arena     ${mb(num('X-Arena-Bytes'))} of ${mb(num('X-Arena-Budget-Bytes'))} MB`,
      `frame     ${frameMs === null ? '–' : frameMs.toFixed(1)} ms (${still ? 'still' : 'moving'})`,
      `rate      ${fps === null ? '–' : fps.toFixed(1)} fps`,
    ].join('\n');
  }

  // ---- picking ----

  // Picks the object under a click, with the camera and size of the displayed frame (so that what
  // is picked is what the user sees even while a newer frame is on its way). The browser stretches
  // the image over the element, so client pixels scale to image pixels by w / element width.
  async function pick(clientX, clientY) {
    if (!shown) return;
    const rect = frame.getBoundingClientRect();
    const x = clamp(Math.floor((clientX - rect.left) * shown.w / rect.width), 0, shown.w - 1);
    const y = clamp(Math.floor((clientY - rect.top) * shown.h / rect.height), 0, shown.h - 1);
    const seq = ++pickSeq;
    try {
      const response = await fetch(`api/pick?${shown.params}&x=${x}&y=${y}`, { cache: 'no-store' });
      if (!response.ok) {
        if (seq === pickSeq) showError(`pick: ${await errorText(response)}`);
        return;
      }
      const body = await response.json();
      if (seq !== pickSeq) return;
      hooks.lastPick = body.object ?? null;
      showPick(hooks.lastPick);
    } catch (e) {
      if (seq === pickSeq) showError(`pick: ${e.message}`);
    }
  }

  // The side panel: name, class, id and attributes of an object, or "nothing here". Text only
  // (textContent): names and attributes come from the model and are never HTML.
  function showPick(object) {
    const el = (tag, text) => { const e = document.createElement(tag); if (text !== undefined) e.textContent = text; return e; };
    pickPanel.replaceChildren();
    if (!object) {
      const p = el('p', 'nothing here');
      p.className = 'hint';
      pickPanel.append(p);
      return;
    }
    const table = el('table');
    const row = (key, value) => { const tr = el('tr'); tr.append(el('th', key), el('td', value)); table.append(tr); };
    row('class', object.class ?? '');
    row('id', object.id ?? '');
    for (const a of object.attributes ?? []) row(a.key, a.value);
    pickPanel.append(el('h2', object.name || '(unnamed)'), table);
  }

  // ---- start ----

  // Loads the model and starts from its camera (or, lacking one, a view of its bounds from the
  // south-west, above). Retries while the server is not answering.
  async function start() {
    try {
      const response = await fetch('api/model', { cache: 'no-store' });
      if (!response.ok) throw new Error(await errorText(response));
      model = await response.json();
    } catch (e) {
      showError(`model: ${e.message}; retrying`);
      setTimeout(start, 2000);
      return;
    }
    showError('');
    statsLines.textContent = `${(model.objects ?? 0).toLocaleString('en-US')} objects; rendering…`;
    let c = model.camera;
    if (!c) {
      const { min, max } = model.bounds;
      const centre = scale(add(min, max), 0.5);
      const size = Math.max(1, length(sub(max, min)));
      c = { eye: add(centre, scale([-0.6, -0.6, 0.5], size)), target: centre, up: Z_UP, fov: 45 };
    }
    camera = { eye: [...c.eye], target: [...c.target], up: [...c.up], fov: c.fov };
    hooks.camera = camera;
    pump();  // at rest: the first frame is a still
  }

  start();
})();
