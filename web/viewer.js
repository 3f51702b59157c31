// plantview viewer. Every frame is rendered by `plantview serve`; this page only moves a camera,
// asks for images of it and shows them.
//
// Camera conventions: model space in metres, z up. eye, target and up are [x, y, z] arrays of
// doubles (plants sit at large coordinates: never round them); fov is the vertical field of view
// in degrees, and the image's aspect ratio is that of the w×h requested. The model's camera is used
// as given until the first move; orbiting and walking then keep up = +z.
//
// Quality: while the camera moves the page asks for mode=interactive frames (cheap: JPEG quality
// 60, a coarser pixel error); REST_MS after the last move it asks once for a mode=still frame (full
// quality). Under load the server may render interactive frames cheaper still, and says so in the
// X-Plantview-* response headers, which the readout shows; a server without them is shown what
// was asked for.
//
// A server started with --token needs it on every API request: open the page as
// http://host:port/#token=TOKEN. The page (index.html, viewer.js, viewer.css) is served without
// it; the token stays in this tab (sessionStorage), is sent as `Authorization: Bearer`, and is
// taken out of the address bar so that it is not shared with a copied link.
//
// Test hooks (tests/browser/test_viewer.py reads them): window.plantview = {
//   camera,       the current camera {eye, target, up, fov} (replaced, never mutated, on a change)
//   home,         the home camera (the model's), which Home flies back to
//   framesShown,  frames displayed since the page loaded
//   framesByMode, of those, how many in each mode: {interactive, still} (as the server reports it,
//                 else as asked)
//   lastPick,     the object of the last pick or search ({id, name, class, attributes, bounds}) or null
//   selected,     the object whose box is drawn over the frame (bounds required), or null
//   flying,       true while the camera flies to an object or home
//   still,        true while the displayed frame is the full-quality still of the current camera
//   quality,      what the displayed frame was rendered with: {mode, reported, degraded,
//                 pixelError, askedPx, jpegQuality, renderSize, requestedSize, queue, renderMs,
//                 roundTripMs},
//                 or null before the first frame
// }
'use strict';

(() => {
  const TOKEN_KEY = 'plantview.token';
  {
    const given = /(?:^#|&)token=([^&]*)/.exec(location.hash);
    if (given) {
      sessionStorage.setItem(TOKEN_KEY, decodeURIComponent(given[1]));
      history.replaceState(null, '', location.pathname + location.search);
    }
  }
  // fetch() for the API, with the token where the page was given one.
  function api(url, options = {}) {
    const token = sessionStorage.getItem(TOKEN_KEY);
    if (!token) return fetch(url, options);
    return fetch(url, { ...options, headers: { ...(options.headers || {}), Authorization: `Bearer ${token}` } });
  }

  const MOVING = { quality: 60, px: 3 };   // while the camera moves: cheap, coarse frames
  const STILL = { quality: 90, px: 1 };    // once it has rested REST_MS: one full-quality still
  const REST_MS = 250;
  const CLICK_SLOP_PX = 4;                 // a press that moves at most this far is a click (a pick)
  const MAX_SIDE_PX = 4096;                // the server's limit on w and h
  const ORBIT_RAD_PER_PX = 0.005;
  const ELEVATION_LIMIT_RAD = 89 * Math.PI / 180;  // orbit never flips over the poles
  const MIN_DISTANCE_M = 0.1;              // zoom stops this close to the target
  const FLY_MS = 800;                      // a fly-to (search, Home) takes this long
  const FIT_FILL = 0.6;                    // a found object fills this share of the frame
  const FIT_MIN_HALF_SIZE_M = 0.5;         // ... but a small one is framed as if this large
  const FIT_ELEVATION_RAD = [15 * Math.PI / 180, 50 * Math.PI / 180];  // look down on it, not along the ground
  const Z_UP = [0, 0, 1];

  const frame = document.getElementById('frame');
  const statsLines = document.getElementById('stats-lines');
  const statsError = document.getElementById('stats-error');
  const pickPanel = document.getElementById('pick');
  const overlay = document.getElementById('overlay');
  const searchForm = document.getElementById('search');
  const searchText = document.getElementById('search-text');
  const homeButton = document.getElementById('home');

  const hooks = { camera: null, home: null, framesShown: 0, framesByMode: { interactive: 0, still: 0 },
                  lastPick: null, selected: null, flying: false, still: false, quality: null };
  window.plantview = hooks;

  // Names this page's latest-wins slot to the server, which answers an older waiting request of
  // the same client 409 when a newer one arrives, whichever connection the browser sends it on.
  // The server issues the id (X-Plantview-Client on a render answer: adopted from the first); a
  // server from before that takes any name, so the page starts with a random one of its own.
  let clientId = Array.from(crypto.getRandomValues(new Uint32Array(4)), (n) => n.toString(16).padStart(8, '0')).join('');
  let clientIssued = false;
  function adoptClientId(headers) {
    const id = headers.get('X-Plantview-Client');
    if (id && !clientIssued) {
      clientId = id;
      clientIssued = true;
    }
  }

  let model = null;           // GET /api/model
  let camera = null;          // the current camera; replaced only by placeCamera()
  let home = null;            // the model's camera: where the page starts and Home returns
  let shown = null;           // the displayed frame's request: {params, camera, w, h, still, px, quality, startMs}
  let shownUrl = null;        // object URL of the displayed frame (revoked when replaced)
  let inFlight = false;       // at most one frame request is outstanding
  let lastChangeMs = -Infinity;  // performance.now() of the last camera or size change
  let blockedUntilMs = 0;     // after a 503 or a network error: no frame request before this
  let failedParams = null;    // a request the server refused: not repeated until something changes
  let pumpTimer = 0;
  let pickSeq = 0;            // only the answer to the latest pick or search is shown
  let selected = null;        // the object whose box is drawn (has bounds), or null
  let flight = null;          // a fly-to in progress: {from, to, startMs}, or null
  let sendMode = true;        // false once a server has refused the mode parameter (an older one)
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

  // Where a point of model space lands in an image of cam with aspect (width / height): {x, y}
  // in 0..1 from the top left, and depth, the distance along the view direction in metres (not
  // positive: behind the eye, and x, y are meaningless).
  function project(cam, aspect, p) {
    const { forward, right, up } = viewBasis(cam);
    const v = sub(p, cam.eye);
    const depth = dot(v, forward);
    const tanY = Math.tan(cam.fov * Math.PI / 360);
    return { x: 0.5 + 0.5 * dot(v, right) / (depth * tanY * aspect),
             y: 0.5 - 0.5 * dot(v, up) / (depth * tanY), depth };
  }

  // A camera that shows the box `bounds` ({min, max}, metres) filling FIT_FILL of the frame's
  // width or height (whichever is tighter) for an image of `aspect`, looking at its centre from
  // the side `from` looks from (its azimuth; the elevation kept within FIT_ELEVATION_RAD), up +z,
  // fov as `from`'s. Every corner of the box lies in front of the eye.
  function fitCamera(bounds, from, aspect) {
    const centre = scale(add(bounds.min, bounds.max), 0.5);
    let half = scale(sub(bounds.max, bounds.min), 0.5);
    half = half.map((h) => Math.max(h, FIT_MIN_HALF_SIZE_M));
    const back = sub(from.eye, from.target);  // towards the eye
    const azimuth = Math.atan2(back[1], back[0]);
    const elevation = clamp(Math.asin(clamp(back[2] / Math.max(length(back), 1e-9), -1, 1)), ...FIT_ELEVATION_RAD);
    const c = Math.cos(elevation);
    const toEye = [c * Math.cos(azimuth), c * Math.sin(azimuth), Math.sin(elevation)];
    const right = normalize(cross(scale(toEye, -1), Z_UP));
    const up = cross(right, scale(toEye, -1));
    const tanY = Math.tan(from.fov * Math.PI / 360) * FIT_FILL;
    const tanX = tanY * aspect;
    let distance = 0;
    for (let corner = 0; corner < 8; ++corner) {
      const p = [corner & 1 ? half[0] : -half[0], corner & 2 ? half[1] : -half[1], corner & 4 ? half[2] : -half[2]];
      const towardEye = dot(p, toEye);
      distance = Math.max(distance, towardEye + Math.abs(dot(p, right)) / tanX,
                          towardEye + Math.abs(dot(p, up)) / tanY, towardEye + MIN_DISTANCE_M);
    }
    return { eye: add(centre, scale(toEye, distance)), target: centre, up: Z_UP, fov: from.fov };
  }

  // The one place the camera changes: the readout, the hooks and the frame requests follow.
  function placeCamera(cam) {
    camera = cam;
    hooks.camera = camera;
    changed();
  }

  // A move by the user: it ends any fly-to.
  function setCamera(eye, target, up) {
    endFlight();
    placeCamera({ eye, target, up, fov: camera.fov });
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

  // Fly-to: the camera moves from where it is to `to` in FLY_MS (eased at both ends), eye and
  // target each along a straight line; frames are interactive on the way and the still follows at
  // the end. A move by the user ends it where it is.
  function flyTo(to) {
    if (!camera) return;
    flight = { from: camera, to, startMs: performance.now() };
    hooks.flying = true;
    requestAnimationFrame(flyStep);
  }

  function flyStep(nowMs) {
    if (!flight) return;
    const t = clamp((nowMs - flight.startMs) / FLY_MS, 0, 1);
    const s = t * t * (3 - 2 * t);
    const { from, to } = flight;
    const lerp = (a, b) => add(a, scale(sub(b, a), s));
    if (t < 1) {
      placeCamera({ eye: lerp(from.eye, to.eye), target: lerp(from.target, to.target), up: to.up, fov: to.fov });
      requestAnimationFrame(flyStep);
    } else {
      endFlight();
      placeCamera({ eye: [...to.eye], target: [...to.target], up: [...to.up], fov: to.fov });  // exactly there
    }
  }

  function endFlight() {
    flight = null;
    hooks.flying = false;
  }

  function goHome() {
    if (home) flyTo(home);
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

  // Keys typed into the search field are text, not moves.
  const typing = (e) => e.target instanceof HTMLInputElement || e.target instanceof HTMLTextAreaElement;
  window.addEventListener('keydown', (e) => {
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    if (typing(e)) {
      if (e.key === 'Escape') e.target.blur();
      return;
    }
    if (e.key === 'Home') { e.preventDefault(); goHome(); return; }
    if (e.key === 'Escape') { pickSeq += 1; select(null); showPick(undefined); return; }
    if (e.key === '/') { e.preventDefault(); searchText.focus(); searchText.select(); return; }
    const key = e.key.toLowerCase();
    if (!'wasdqe'.includes(key) || key.length !== 1 || !camera) return;
    e.preventDefault();
    endFlight();
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
    if (document.activeElement instanceof HTMLElement) document.activeElement.blur();  // keys walk again
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
  window.addEventListener('resize', () => { drawOverlay(); if (camera) changed(); });
  homeButton.addEventListener('click', () => { homeButton.blur(); goHome(); });
  searchForm.addEventListener('submit', (e) => {
    e.preventDefault();
    search(searchText.value);
  });

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
                `${sendMode ? `&mode=${still ? 'still' : 'interactive'}` : ''}&client=${encodeURIComponent(clientId)}`;
    const request = { params, camera, w, h, still, px: q.px, quality: q.quality, startMs: nowMs };
    fetchFrame(url, request).finally(() => { inFlight = false; pump(); });
  }

  async function fetchFrame(url, request) {
    try {
      const response = await api(url, { cache: 'no-store' });
      adoptClientId(response.headers);
      if (response.status === 409) return;  // superseded by a newer request of ours: ignore
      if (response.status === 503) {
        const seconds = parseFloat(response.headers.get('Retry-After'));
        const waitMs = 1000 * (Number.isFinite(seconds) && seconds >= 0 ? seconds : 1);
        blockedUntilMs = performance.now() + waitMs;
        showError(`server busy: retrying in ${(waitMs / 1000).toFixed(1)} s`);
        return;
      }
      if (!response.ok) {
        const text = await errorText(response);
        if (response.status === 400 && sendMode && text.includes("'mode'")) {
          sendMode = false;  // a server from before mode=interactive|still: ask it without
          return;
        }
        failedParams = request.params;
        showError(`frame: ${text}`);
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
      hooks.quality = qualityOf(response.headers, request, performance.now() - request.startMs);
      hooks.framesByMode[hooks.quality.mode] = (hooks.framesByMode[hooks.quality.mode] ?? 0) + 1;
      showStats(response.headers, hooks.quality);
      drawOverlay();
      showError('');
    } catch (e) {
      // The network (the server restarting?): try again in a little while.
      blockedUntilMs = performance.now() + 2000;
      showError(`frame: ${e.message}`);
    }
  }

  async function errorText(response) {
    if (response.status === 401)
      return `401: this server needs its token: open the page as ${location.origin}${location.pathname}#token=TOKEN`;
    try {
      const body = await response.json();
      if (body && body.error) return `${response.status}: ${body.error}`;
    } catch { /* not JSON */ }
    return `${response.status} ${response.statusText}`;
  }

  function showError(text) { statsError.textContent = text; }

  // What the displayed frame was rendered with, from the X-Plantview-* headers where the server
  // sends them, else from what was asked for (and the decoded image's size).
  function qualityOf(headers, request, roundTripMs) {
    const num = (name) => { const v = parseFloat(headers.get(name)); return Number.isFinite(v) ? v : null; };
    const size = /^(\d+)x(\d+)$/.exec(headers.get('X-Plantview-Render-Size') ?? '');
    const degraded = headers.get('X-Plantview-Degraded');
    const frameMs = num('X-Frame-Ms'), encodeMs = num('X-Encode-Ms');
    return {
      mode: headers.get('X-Plantview-Mode') ?? (request.still ? 'still' : 'interactive'),
      reported: headers.has('X-Plantview-Mode'),  // false: an older server, the rest is inferred
      degraded: degraded === null ? [] : degraded.split(',').map((d) => d.trim()).filter((d) => d && d !== 'none'),
      pixelError: num('X-Plantview-Pixel-Error') ?? request.px,
      askedPx: request.px,
      jpegQuality: num('X-Plantview-Jpeg-Quality') ?? request.quality,
      renderSize: size ? [Number(size[1]), Number(size[2])] : [frame.naturalWidth, frame.naturalHeight],
      requestedSize: [request.w, request.h],
      queue: num('X-Plantview-Queue'),
      renderMs: num('X-Plantview-Render-Ms') ?? (frameMs === null ? null : frameMs + (encodeMs ?? 0)),
      roundTripMs,
    };
  }

  // The overlay: the displayed frame's statistics (from its response headers), the quality it was
  // rendered with and why, and the frame rate achieved over the last two seconds with what limits it.
  function showStats(headers, quality) {
    const nowMs = performance.now();
    shownTimesMs.push(nowMs);
    while (shownTimesMs.length > 1 && nowMs - shownTimesMs[0] > 2000) shownTimesMs.shift();
    const n = shownTimesMs.length;
    const fps = n > 1 ? (n - 1) * 1000 / (nowMs - shownTimesMs[0]) : null;
    const num = (name) => { const v = parseFloat(headers.get(name)); return Number.isFinite(v) ? v : null; };
    const count = (v) => (v === null ? '–' : v.toLocaleString('en-US'));
    const mb = (v) => (v === null ? '–' : (v / 1048576).toFixed(1));
    const ms = (v) => (v === null ? '–' : `${Math.round(v)} ms`);
    const q = quality;
    const [rw, rh] = q.renderSize, [qw, qh] = q.requestedSize;
    const scaled = rw > 0 && (rw !== qw || rh !== qh);
    const busy = q.queue !== null && q.queue > 0 ? `server busy: ${q.queue} waiting` : null;

    // quality: the mode, then what was given up (the reason is on the rate line), or that nothing was.
    const parts = [q.mode];
    const pxText = `px ${q.pixelError}`, sizeText = scaled ? `${rw}x${rh} scaled to ${qw}x${qh}` : `${qw}x${qh}`;
    const jpegText = `JPEG ${q.jpegQuality}`;
    if (q.degraded.length > 0) {
      const given = q.degraded.map((d) => (d === 'pixel-error' ? `${pxText} instead of ${q.askedPx}`
                                           : d === 'resolution' ? sizeText : d));
      parts.push(`degraded: ${given.join(', ')}`);
      if (!q.degraded.includes('pixel-error')) parts.push(pxText);
      if (!q.degraded.includes('resolution')) parts.push(sizeText);
      parts.push(jpegText);
    } else {
      if (q.mode === 'still') parts.push('full quality');
      parts.push(pxText, sizeText, jpegText);
    }
    if (!q.reported) parts.push('(as asked; the server reports no quality)');

    // rate: at rest there is no rate to speak of, only how long the still took; while moving, the
    // rate and what takes the time (one frame is requested at a time, so the round trip is it).
    let rate;
    const renderOf = q.renderMs === null ? '' : `, render ${ms(q.renderMs)}`;
    if (q.mode === 'still' && !flight && held.size === 0 && !drag) {
      rate = `at rest · the still took ${ms(q.roundTripMs)}${renderOf}`;
    } else {
      // The page asks for the next frame when one arrives and the camera has moved: a round trip
      // well under the interval between frames means the server keeps up with the moves.
      const intervalMs = fps === null ? null : 1000 / fps;
      const why = busy ?? (intervalMs !== null && q.roundTripMs < 0.6 * intervalMs
        ? `the server keeps up: ${ms(q.roundTripMs)} a frame`
        : q.renderMs === null ? `${ms(q.roundTripMs)} a frame`
        : q.renderMs >= q.roundTripMs / 2 ? `rendering: ${ms(q.renderMs)} of ${ms(q.roundTripMs)} a frame`
        : `network and queue: ${ms(q.roundTripMs - q.renderMs)} of ${ms(q.roundTripMs)} a frame`);
      rate = `${fps === null ? '–' : fps.toFixed(1)} fps · ${why}`;
    }
    statsLines.textContent = [
      `triangles ${count(num('X-Triangles'))}`,
      `objects   ${count(num('X-Objects-Visible'))} visible of ${count(model.objects ?? null)}`,
      `arena     ${mb(num('X-Arena-Bytes'))} of ${mb(num('X-Arena-Budget-Bytes'))} MB`,
      `quality   ${parts.join(' · ')}`,
      `rate      ${rate}`,
    ].join('\n');
  }

  // ---- the selection's box ----

  // Draws the selected object's bounds as a box over the displayed frame, projected with the
  // camera that frame was rendered with (so that box and image agree while a newer frame is on its
  // way). Edges are clipped where they pass behind the eye.
  function drawOverlay() {
    const dpr = window.devicePixelRatio || 1;
    const cssW = overlay.clientWidth, cssH = overlay.clientHeight;
    if (overlay.width !== Math.round(cssW * dpr) || overlay.height !== Math.round(cssH * dpr)) {
      overlay.width = Math.round(cssW * dpr);
      overlay.height = Math.round(cssH * dpr);
    }
    const g = overlay.getContext('2d');
    g.setTransform(1, 0, 0, 1, 0, 0);
    g.clearRect(0, 0, overlay.width, overlay.height);
    if (!selected || !selected.bounds || !shown) return;
    g.scale(dpr, dpr);
    const aspect = shown.w / shown.h;
    const { min, max } = selected.bounds;
    const corner = (i) => [i & 1 ? max[0] : min[0], i & 2 ? max[1] : min[1], i & 4 ? max[2] : min[2]];
    const near = 0.05;  // metres: the renderer's near plane
    const edges = [];
    for (let i = 0; i < 8; ++i)
      for (const bit of [1, 2, 4]) if (!(i & bit)) edges.push([corner(i), corner(i | bit)]);
    g.lineWidth = 2;
    g.strokeStyle = '#ffcc33';
    g.shadowColor = 'rgba(0, 0, 0, 0.8)';
    g.shadowBlur = 3;
    g.beginPath();
    let top = null;  // the highest point drawn, for the label
    for (let [a, b] of edges) {
      let pa = project(shown.camera, aspect, a), pb = project(shown.camera, aspect, b);
      if (pa.depth < near && pb.depth < near) continue;
      if (pa.depth < near || pb.depth < near) {  // cut the edge where it crosses the near plane
        const t = (near - pa.depth) / (pb.depth - pa.depth);
        const cut = project(shown.camera, aspect, add(a, scale(sub(b, a), t)));
        if (pa.depth < near) pa = cut; else pb = cut;
      }
      g.moveTo(pa.x * cssW, pa.y * cssH);
      g.lineTo(pb.x * cssW, pb.y * cssH);
      for (const p of [pa, pb]) if (!top || p.y < top.y) top = p;
    }
    g.stroke();
    if (top) {
      g.shadowBlur = 4;
      g.font = 'bold 13px system-ui, sans-serif';
      g.fillStyle = '#ffcc33';
      g.textAlign = 'center';
      g.fillText(selected.name || selected.id || '', clamp(top.x * cssW, 60, cssW - 60), clamp(top.y * cssH - 8, 16, cssH - 4));
    }
  }

  function select(object) {
    selected = object && object.bounds ? object : null;
    hooks.selected = selected;
    drawOverlay();
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
      const response = await api(`api/pick?${shown.params}&x=${x}&y=${y}&client=${encodeURIComponent(clientId)}`,
                                   { cache: 'no-store' });
      adoptClientId(response.headers);
      if (!response.ok) {
        if (seq === pickSeq) showError(`pick: ${await errorText(response)}`);
        return;
      }
      const body = await response.json();
      if (seq !== pickSeq) return;
      hooks.lastPick = body.object ?? null;
      showPick(hooks.lastPick);
      select(hooks.lastPick);
    } catch (e) {
      if (seq === pickSeq) showError(`pick: ${e.message}`);
    }
  }

  // Finds an object by what the user typed: a tag or name (as given, then with the leading '/'
  // that plant names carry, so "P-101A" finds "/P-101A") or an id, through /api/objects/. A found
  // object is shown as a pick is, selected, and flown to (its bounds filling FIT_FILL of the frame).
  async function search(text) {
    const query = text.trim();
    if (!query || !model) return;
    const seq = ++pickSeq;
    const names = [query];
    if (!query.startsWith('/') && !/^[0-9]+$/.test(query)) names.push(`/${query}`);
    let firstError = null;
    try {
      for (const name of names) {
        // Each segment escaped, the '/' between them kept: a server that does not decode the path
        // still sees the name as stored.
        const path = name.split('/').map(encodeURIComponent).join('/');
        const response = await api(`api/objects/${path}`, { cache: 'no-store' });
        if (seq !== pickSeq) return;
        if (response.ok) {
          const object = await response.json();
          if (seq !== pickSeq) return;
          showError('');
          searchText.blur();  // keys walk again
          hooks.lastPick = object;
          showPick(object);
          select(object);
          if (object.bounds) {
            const { w, h } = frameSize();
            flyTo(fitCamera(object.bounds, camera, w / h));
          } else {
            showError(`find: ${object.name || object.id} has no geometry of its own to fly to`);
          }
          return;
        }
        firstError ??= await errorText(response);
        if (response.status !== 404 && response.status !== 400) break;
      }
      if (seq === pickSeq) showError(`find '${query}': ${firstError}`);
    } catch (e) {
      if (seq === pickSeq) showError(`find: ${e.message}`);
    }
  }

  // The side panel: name, class, id and attributes of an object, "nothing here" (null), or the
  // hint the page starts with (undefined). Text only (textContent): names and attributes come
  // from the model and are never HTML.
  const hint = pickPanel.firstElementChild;
  function showPick(object) {
    const el = (tag, text) => { const e = document.createElement(tag); if (text !== undefined) e.textContent = text; return e; };
    pickPanel.replaceChildren();
    if (object === undefined) {
      pickPanel.append(hint);
      return;
    }
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
      const response = await api('api/model', { cache: 'no-store' });
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
    home = { eye: [...c.eye], target: [...c.target], up: [...c.up], fov: c.fov };
    hooks.home = home;
    camera = home;
    hooks.camera = camera;
    pump();  // at rest: the first frame is a still
  }

  start();
})();
