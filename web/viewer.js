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
// Transport: frames come over the WebSocket stream (/api/stream) by default, as video where the
// browser decodes it (WebCodecs), else JPEG; HTTP frames (GET /api/frame) where the stream cannot
// open. See "the frame stream" below.
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
//   frameParams,  the query (camera, size, filters) of the displayed frame
//   section,      {box: {min, max} or null, planes: [{point, normal}] as sent, caps}
//   sectionHandles, the box's face handles as drawn: [{face (0..5: -x, +x, -y, +y, -z, +z), x, y}]
//                 in CSS pixels of the page
//   style,        {colourBy, hide, only, isolate}
//   legend,       the displayed frame's X-Plantview-Legend (parsed), or null
//   measure,      the last measurement {kind: points|objects, a, b, distance_m, dx_m, dy_m, dz_m, ...}
//                 or null
//   permalink,    the page's address with the view in its fragment
//   lastBcf,      the last saved viewpoint {name, topic, size, base64}, or null
//   picksAnswered, picks whose answers have come (or failed) since the page loaded
//   stream,       how frames come: {transport: stream|http, codec: jpeg|h264|vp8|null, kbps, fps,
//                 latencyMs (view sent to frame shown), frames (shown from the stream), videoFrames
//                 (of those, decoded by WebCodecs), fellBack
//                 (times the stream closed or could not open: HTTP frames then)}
// }
//
// Review tools (the panel under the search):
//   Section: "Box" puts a section box around the selection (else the plant); drag its face
//     handles along their normals; "plan cut" and the slider cut away all above an elevation
//     (clip=0,0,Z,0,0,1); caps fills cut solids; Reset. Sent as box= and clip= (and caps=0).
//   Measure: points (two clicks; the picks' point_m) or clearance (two objects; /api/measure).
//   Colour, hide, only: colour_by=, hide=, only=; the frame's legend is shown bottom right.
//     "highlight the selection" sends it as highlight= (the rest ghosted).
//   Viewpoint: saves a BCF 2.1 file (camera, clipping, selection, a PNG snapshot), opens one.
//   The address bar's fragment always holds the view (permalink; see readLink).
'use strict';

(() => {
  const TOKEN_KEY = 'plantview.token';
  {
    const given = /(?:^#|&)token=([^&]*)/.exec(location.hash);
    if (given) {
      sessionStorage.setItem(TOKEN_KEY, decodeURIComponent(given[1]));
      // The rest of the fragment (a permalink's view) stays.
      const rest = location.hash.slice(1).split('&').filter((part) => !part.startsWith('token=')).join('&');
      history.replaceState(null, '', location.pathname + location.search + (rest ? `#${rest}` : ''));
    }
  }
  // fetch() for the API, with the token where the page was given one.
  // Every answer says the revision its data came from (X-Plantview-Revision): a newer one than
  // shown is noticed (noticeRevision, below) whatever asked.
  function api(url, options = {}) {
    const token = sessionStorage.getItem(TOKEN_KEY);
    const sent = !token ? fetch(url, options)
      : fetch(url, { ...options, headers: { ...(options.headers || {}), Authorization: `Bearer ${token}` } });
    return sent.then((response) => { noticeRevision(response.headers); return response; });
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
  const NEAR_M = 0.05;                     // the renderer's near plane: overlay edges are cut there
  const MAX_CLIP_PLANES = 6;               // the server's limit on clip= parameters
  const HANDLE_RADIUS_PX = 6;              // a section box face's handle, as drawn
  const HANDLE_HIT_PX = 10;                // a press this close to a handle drags its face
  const LINK_MS = 250;                     // the permalink is rewritten at most this often

  const frame = document.getElementById('frame');
  const statsLines = document.getElementById('stats-lines');
  const statsError = document.getElementById('stats-error');
  const pickPanel = document.getElementById('pick');
  const overlay = document.getElementById('overlay');
  const searchForm = document.getElementById('search');
  const searchText = document.getElementById('search-text');
  const homeButton = document.getElementById('home');

  const hooks = { camera: null, home: null, framesShown: 0, framesByMode: { interactive: 0, still: 0 },
                  lastPick: null, selected: null, flying: false, still: false, quality: null,
                  frameParams: null, section: null, sectionHandles: [], style: null, legend: null,
                  measure: null, permalink: null, lastBcf: null, picksAnswered: 0 };
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
  // Following imports: the revision shown (model.revision), the one an update came from, and
  // whether frames show what changed since it (changes=R, frames only).
  let revision = null;
  let updatedFrom = null;
  let showChanges = false;
  let describing = false;     // an /api/model request for a new revision is out
  // The view's filters (sent with every request; see filterParams): the section box {min, max}
  // or null, clip planes [{point, normal}] (from an opened viewpoint), the plan cut's elevation
  // or null, caps; colour by, hide and only as typed; isolate: the selection is highlighted.
  const section = { box: null, planes: [], planZ: null, caps: true };
  const style = { colourBy: '', hide: '', only: '' };
  let isolate = false;
  // The measure tool: mode off | points | objects, the picks so far, the last result.
  const measure = { mode: 'off', picks: [], result: null };

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
    scheduleLink();
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
    if (e.key === 'Escape') { pickSeq += 1; select(null); showPick(undefined); clearMeasure(); return; }
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
    // A left press on a section box's handle drags that face.
    const handle = e.button === 0 && !e.shiftKey ? handleAt(e.clientX, e.clientY) : null;
    drag = { id: e.pointerId, x0: e.clientX, y0: e.clientY, x: e.clientX, y: e.clientY,
             moved: false, pan: e.button !== 0 || e.shiftKey,
             face: handle ? handle.face : null, box: handle ? section.box : null };
  });
  frame.addEventListener('pointermove', (e) => {
    if (!drag) frame.classList.toggle('on-handle', section.box !== null && handleAt(e.clientX, e.clientY) !== null);
    if (!drag || e.pointerId !== drag.id) return;
    if (drag.face !== null) {
      drag.moved = true;
      dragFace(drag.face, drag.box, e.clientX - drag.x0, e.clientY - drag.y0);
      return;
    }
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
    if (isClick && !drag.moved && !drag.pan && drag.face === null)
      (measure.mode === 'off' ? pick : measurePick)(e.clientX, e.clientY);
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
    const params = viewParams(camera, w, h);
    if (shown && shown.params === params && (shown.still || !still)) return;  // already showing it
    if (params === failedParams) return;
    const q = still ? STILL : MOVING;
    if (stream.open) {  // the stream renders the latest view sent: no request to wait for
      streamView(params, { params, camera, w, h, still, px: q.px, quality: q.quality, startMs: nowMs });
      return;
    }
    if (stream.opening) return;  // pump() again once the stream is open or has failed
    inFlight = true;
    const url = `api/frame?${params}&format=jpeg&quality=${q.quality}&lod=screen-space&px=${q.px}` +
                `${showChanges && updatedFrom !== null ? `&changes=${updatedFrom}` : ''}` +
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
      videoCanvas.hidden = true;
      frameShown(response.headers, request, performance.now() - request.startMs);
    } catch (e) {
      // The network (the server restarting?): try again in a little while.
      blockedUntilMs = performance.now() + 2000;
      showError(`frame: ${e.message}`);
    }
  }

  // A frame is on screen (from an HTTP answer, or the stream): the hooks, legend, readout.
  function frameShown(headers, request, roundTripMs) {
    shown = request;
    hooks.framesShown += 1;
    const { w, h } = frameSize();
    hooks.still = request.still && request.params === viewParams(camera, w, h);
    hooks.frameParams = request.params;
    showLegend(headers.get('X-Plantview-Legend'));
    hooks.quality = qualityOf(headers, request, roundTripMs);
    hooks.framesByMode[hooks.quality.mode] = (hooks.framesByMode[hooks.quality.mode] ?? 0) + 1;
    showStats(headers, hooks.quality);
    drawOverlay();
    showError('');
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
      `transport ${transportText()}`,
    ].join('\n');
  }

  // ---- the overlay: the selection's box, the section box and the measurement ----

  // Draws the selected object's bounds as a box over the displayed frame, projected with the
  // camera that frame was rendered with (so that box and image agree while a newer frame is on its
  // way), and under it the section box with its face handles and the measure tool's points and
  // line. Edges are clipped where they pass behind the eye.
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
    if (!shown) return;
    g.scale(dpr, dpr);
    const aspect = shown.w / shown.h;
    drawSection(g, aspect);
    drawMeasure(g, aspect);
    if (!selected || !selected.bounds) return;
    const top = drawBox(g, aspect, selected.bounds, '#ffcc33', 2);
    if (top) {
      g.shadowBlur = 4;
      g.font = 'bold 13px system-ui, sans-serif';
      g.fillStyle = '#ffcc33';
      g.textAlign = 'center';
      g.fillText(selected.name || selected.id || '', clamp(top.x * cssW, 60, cssW - 60), clamp(top.y * cssH - 8, 16, cssH - 4));
    }
    g.shadowBlur = 0;
  }

  // Draws the 12 edges of the box `bounds` ({min, max}) with the displayed frame's camera; returns
  // the highest point drawn (for a label), or null.
  function drawBox(g, aspect, bounds, colour, widthPx) {
    const cssW = overlay.clientWidth, cssH = overlay.clientHeight;
    const { min, max } = bounds;
    const corner = (i) => [i & 1 ? max[0] : min[0], i & 2 ? max[1] : min[1], i & 4 ? max[2] : min[2]];
    const near = NEAR_M;
    const edges = [];
    for (let i = 0; i < 8; ++i)
      for (const bit of [1, 2, 4]) if (!(i & bit)) edges.push([corner(i), corner(i | bit)]);
    g.lineWidth = widthPx;
    g.strokeStyle = colour;
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
    g.shadowBlur = 0;
    return top;
  }

  // The selection changes: its box is drawn, the permalink holds it, and where the selection is
  // highlighted, frames follow.
  function select(object) {
    const before = selected;
    selected = object && object.bounds ? object : null;
    hooks.selected = selected;
    if (isolate && (before?.id ?? null) !== (selected?.id ?? null)) filtersChanged();
    else { drawOverlay(); scheduleLink(); }
  }

  // ---- picking ----

  // Picks the object under a click, with the camera and size of the displayed frame (so that what
  // is picked is what the user sees even while a newer frame is on its way). The browser stretches
  // the image over the element, so client pixels scale to image pixels by w / element width.
  // The pick answer ({object, point_m?, normal?}) for a click, or null (an error shown, or a
  // newer pick asked meanwhile). The displayed frame's filters go with it.
  async function pickAt(clientX, clientY) {
    if (!shown) return null;
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
        return null;
      }
      const body = await response.json();
      return seq === pickSeq ? body : null;
    } catch (e) {
      if (seq === pickSeq) showError(`pick: ${e.message}`);
      return null;
    } finally {
      hooks.picksAnswered += 1;
    }
  }

  async function pick(clientX, clientY) {
    const body = await pickAt(clientX, clientY);
    if (!body) return;
    hooks.lastPick = body.object ?? null;
    showPick(hooks.lastPick);
    select(hooks.lastPick);
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

  // ---- view filters: section, styling, highlight ----

  // The query parameters of the view's filters, appended to every frame, stats and pick request
  // (and held in the permalink): clip= (the BCF planes, then the plan cut; at most 6), box=,
  // caps=0, colour_by=, hide=, only=, highlight= (the selection, when isolate is on).
  function filterParams() {
    const parts = [];
    for (const p of allPlanes()) parts.push(`clip=${[...p.point, ...p.normal].join(',')}`);
    if (section.box) parts.push(`box=${[...section.box.min, ...section.box.max].join(',')}`);
    if (!section.caps && (section.box || allPlanes().length > 0)) parts.push('caps=0');
    if (style.colourBy) parts.push(`colour_by=${encodeURIComponent(style.colourBy)}`);
    if (style.hide) parts.push(`hide=${encodeURIComponent(style.hide)}`);
    if (style.only) parts.push(`only=${encodeURIComponent(style.only)}`);
    if (isolate && selected) parts.push(`highlight=${encodeURIComponent(selected.id)}`);
    return parts.length ? `&${parts.join('&')}` : '';
  }

  // The camera, size and filters of a request (frame, stats and pick share them).
  function viewParams(cam, w, h) { return cameraParams(cam, w, h) + filterParams(); }

  // The clip planes sent: those of an opened viewpoint, then the plan cut (removes all above z).
  function allPlanes() {
    const planes = [...section.planes];
    if (section.planZ !== null) planes.push({ point: [0, 0, section.planZ], normal: [0, 0, 1] });
    return planes.slice(0, MAX_CLIP_PLANES);
  }

  // A filter changed: new frames, and the permalink follows.
  function filtersChanged() {
    hooks.section = { box: section.box, planes: allPlanes(), caps: section.caps };
    hooks.style = { ...style, isolate };
    drawOverlay();
    if (camera) changed();
  }

  const mm = (v) => Math.round(v * 1000) / 1000;  // metres to the millimetre (shorter URLs)

  // The section box: around the selection (a margin of a tenth of its size, at least 0.5 m),
  // else the whole plant.
  function sectionBoxAround() {
    const bounds = selected?.bounds ?? model?.bounds;
    if (!bounds) return null;
    const margin = sub(bounds.max, bounds.min).map((d) => Math.max(0.5, 0.1 * d));
    return { min: sub(bounds.min, margin).map(mm), max: add(bounds.max, margin).map(mm) };
  }

  // Face f of the box (0..5: -x, +x, -y, +y, -z, +z): its centre and outward normal.
  function boxFace(box, f) {
    const axis = f >> 1, sign = f & 1 ? 1 : -1;
    const centre = scale(add(box.min, box.max), 0.5);
    centre[axis] = sign > 0 ? box.max[axis] : box.min[axis];
    const normal = [0, 0, 0];
    normal[axis] = sign;
    return { axis, sign, centre, normal };
  }

  // Where the handles of the box's faces are drawn, in CSS pixels of the overlay (with the camera
  // of the displayed frame; handles behind the eye are left out).
  function sectionHandles() {
    if (!section.box || !shown) return [];
    const aspect = shown.w / shown.h, cssW = overlay.clientWidth, cssH = overlay.clientHeight;
    const handles = [];
    for (let f = 0; f < 6; ++f) {
      const p = project(shown.camera, aspect, boxFace(section.box, f).centre);
      if (p.depth > NEAR_M) handles.push({ face: f, x: p.x * cssW, y: p.y * cssH });
    }
    return handles;
  }

  function handleAt(clientX, clientY) {
    const rect = overlay.getBoundingClientRect();
    let best = null;
    for (const h of sectionHandles()) {
      const d = Math.hypot(clientX - rect.left - h.x, clientY - rect.top - h.y);
      if (d <= HANDLE_HIT_PX && (!best || d < best.d)) best = { ...h, d };
    }
    return best;
  }

  // Drags face `face` of the box from `start` (the box when the drag began) by the pointer's
  // movement since then (CSS px), along the face's normal as the camera shows it; the face stops
  // at the opposite one.
  function dragFace(face, start, dxPx, dyPx) {
    const { axis, sign, centre, normal } = boxFace(start, face);
    const aspect = shown.w / shown.h, cssW = overlay.clientWidth, cssH = overlay.clientHeight;
    const stepM = Math.max(0.01, 0.1 * length(sub(start.max, start.min)));
    const p0 = project(camera, aspect, centre), p1 = project(camera, aspect, add(centre, scale(normal, stepM)));
    if (p0.depth <= NEAR_M || p1.depth <= NEAR_M) return;
    const vx = (p1.x - p0.x) * cssW / stepM, vy = (p1.y - p0.y) * cssH / stepM;  // px per metre
    const v2 = vx * vx + vy * vy;
    if (v2 < 1e-6) return;  // the normal points at the eye: no way to drag along it
    const moveM = (dxPx * vx + dyPx * vy) / v2;
    const box = { min: [...start.min], max: [...start.max] };
    if (sign > 0) box.max[axis] = mm(Math.max(start.min[axis], start.max[axis] + moveM));
    else box.min[axis] = mm(Math.min(start.max[axis], start.min[axis] - moveM));
    section.box = box;
    filtersChanged();
  }

  function drawSection(g, aspect) {
    hooks.sectionHandles = [];
    if (!section.box) return;
    drawBox(g, aspect, section.box, '#4fc3f7', 1.5);
    const handles = sectionHandles();
    hooks.sectionHandles = handles.map(({ face, x, y }) => ({ face, x, y }));
    g.fillStyle = '#4fc3f7';
    g.strokeStyle = '#0b3a4f';
    g.lineWidth = 1.5;
    for (const h of handles) {
      g.beginPath();
      g.arc(h.x, h.y, HANDLE_RADIUS_PX, 0, 2 * Math.PI);
      g.fill();
      g.stroke();
    }
  }

  const sectionBoxButton = document.getElementById('section-box');
  const sectionReset = document.getElementById('section-reset');
  const sectionCaps = document.getElementById('section-caps');
  const planCut = document.getElementById('plan-cut');
  const planZ = document.getElementById('plan-z');
  const elevation = document.getElementById('elevation');
  sectionBoxButton.addEventListener('click', () => {
    sectionBoxButton.blur();
    section.box = sectionBoxAround();
    filtersChanged();
  });
  sectionReset.addEventListener('click', () => {
    sectionReset.blur();
    section.box = null;
    section.planes = [];
    section.planZ = null;
    planCut.checked = false;
    filtersChanged();
  });
  // Checkboxes give the keys back to walking once changed (a focused input takes them).
  sectionCaps.addEventListener('change', () => { sectionCaps.blur(); section.caps = sectionCaps.checked; filtersChanged(); });
  function setPlanCut() {
    section.planZ = planCut.checked ? mm(Number(elevation.value)) : null;
    planZ.textContent = `${mm(Number(elevation.value)).toFixed(2)} m`;
    filtersChanged();
  }
  planCut.addEventListener('change', () => { planCut.blur(); setPlanCut(); });
  elevation.addEventListener('input', () => { if (!planCut.checked) planCut.checked = true; setPlanCut(); });
  function setElevationRange() {
    if (!model?.bounds) return;
    elevation.min = model.bounds.min[2];
    elevation.max = model.bounds.max[2];
    elevation.step = Math.max(0.01, (model.bounds.max[2] - model.bounds.min[2]) / 500);
    elevation.value = section.planZ ?? model.bounds.max[2];
    planCut.checked = section.planZ !== null;
    planZ.textContent = `${Number(elevation.value).toFixed(2)} m`;
  }

  // ---- colour by, hide, only, highlight ----

  const styleForm = document.getElementById('style-form');
  const colourByInput = document.getElementById('colour-by');
  const hideInput = document.getElementById('hide');
  const onlyInput = document.getElementById('only');
  const isolateInput = document.getElementById('isolate');
  const legendPanel = document.getElementById('legend');
  styleForm.addEventListener('submit', (e) => {
    e.preventDefault();
    style.colourBy = colourByInput.value.trim();
    style.hide = hideInput.value.trim();
    style.only = onlyInput.value.trim();
    if (document.activeElement instanceof HTMLElement) document.activeElement.blur();
    filtersChanged();
  });
  isolateInput.addEventListener('change', () => { isolateInput.blur(); isolate = isolateInput.checked; filtersChanged(); });
  function showStyleInputs() {
    colourByInput.value = style.colourBy;
    hideInput.value = style.hide;
    onlyInput.value = style.only;
    isolateInput.checked = isolate;
    const keys = model?.attribute_keys ?? [];
    document.getElementById('attribute-keys').replaceChildren(...keys.map((k) => {
      const o = document.createElement('option');
      o.value = k;
      return o;
    }));
  }

  // The legend of the displayed frame (X-Plantview-Legend: {key, kind: "categories", entries:
  // [{value, colour, objects}], other_objects} or {key, kind: "ramp", unit, min, max, colours,
  // objects}); hidden when the frame has none. Text only: values come from the model.
  function showLegend(text) {
    let legend = null;
    try { legend = text ? JSON.parse(text) : null; } catch { legend = null; }
    hooks.legend = legend;
    if (!legend) { legendPanel.hidden = true; legendPanel.replaceChildren(); return; }
    const el = (tag, cls, content) => {
      const e = document.createElement(tag);
      if (cls) e.className = cls;
      if (content !== undefined) e.textContent = content;
      return e;
    };
    const items = [el('h3', '', `colour by ${legend.key ?? ''}`)];
    const colourOk = (c) => (typeof c === 'string' && /^#[0-9a-fA-F]{3,8}$/.test(c) ? c : '#888');
    if (legend.kind === 'ramp') {
      const colours = (legend.colours ?? []).map(colourOk);
      const ramp = el('div', 'ramp');
      ramp.style.background = `linear-gradient(to right, ${colours.length > 1 ? colours.join(', ') : `${colours[0] ?? '#888'}, ${colours[0] ?? '#888'}`})`;
      const unit = legend.unit ? ` ${legend.unit}` : '';
      const ends = el('div', 'ends');
      ends.append(el('span', '', `${legend.min}${unit}`), el('span', '', `${legend.max}${unit}`));
      items.push(ramp, ends, el('div', 'count', `${legend.objects ?? '–'} objects`));
    } else {
      for (const entry of legend.entries ?? []) {
        const row = el('div', 'entry');
        const swatch = el('span', 'swatch');
        swatch.style.background = colourOk(entry.colour);
        row.append(swatch, el('span', '', String(entry.value)), el('span', 'count', String(entry.objects ?? '')));
        items.push(row);
      }
      if (legend.other_objects) items.push(el('div', 'count', `${legend.other_objects} others`));
    }
    legendPanel.replaceChildren(...items);
    legendPanel.hidden = false;
  }

  // ---- measure ----

  const measureResult = document.getElementById('measure-result');
  for (const radio of document.querySelectorAll('input[name="measure-mode"]')) {
    radio.addEventListener('change', () => {
      if (!radio.checked) return;
      measure.mode = radio.value;
      clearMeasure();
      radio.blur();
    });
  }
  function clearMeasure() {
    measure.picks = [];
    measure.result = null;
    hooks.measure = null;
    showMeasure();
    drawOverlay();
  }

  const metres = (v) => `${v.toFixed(3)} m`;
  function showMeasure() {
    const r = measure.result;
    if (r) {
      const lines = [`distance ${metres(r.distance_m)}`,
                     `dx ${metres(r.dx_m)}  dy ${metres(r.dy_m)}  dz ${metres(r.dz_m)}`];
      if (r.kind === 'objects') {
        lines.unshift(`${r.aName} – ${r.bName}`);
        if (r.overlapping) lines.push(`overlapping${Number.isFinite(r.penetration_m) ? ` by ${metres(r.penetration_m)}` : ''}`);
        if (Number.isFinite(r.error_m)) lines.push(`± ${metres(r.error_m)} (${r.method ?? ''})`);
      }
      measureResult.textContent = lines.join('\n');
    } else if (measure.mode === 'off') {
      measureResult.textContent = '';
    } else {
      const what = measure.mode === 'points' ? 'point' : 'object';
      measureResult.textContent = `click the ${measure.picks.length === 0 ? 'first' : 'second'} ${what}`;
    }
  }

  // A click while measuring: points (two picks' point_m) or objects (two picks' objects, then
  // /api/measure for their clearance). A server whose picks carry no point says so.
  async function measurePick(clientX, clientY) {
    const body = await pickAt(clientX, clientY);
    if (!body) return;
    const object = body.object ?? null;
    if (!object) { showError('measure: nothing here: click on an object'); return; }
    if (measure.picks.length >= 2) { measure.picks = []; measure.result = null; }
    if (measure.mode === 'points') {
      const point = body.point_m ?? object.point_m ?? null;
      if (!Array.isArray(point) || point.length !== 3) {
        showError("measure: this server's picks carry no point (point_m): measure the clearance between objects instead");
        return;
      }
      measure.picks.push({ point, normal: body.normal ?? object.normal ?? null, object });
      if (measure.picks.length === 2) {
        const [a, b] = measure.picks;
        const d = sub(b.point, a.point);
        measure.result = { kind: 'points', a: a.point, b: b.point, distance_m: length(d),
                           dx_m: d[0], dy_m: d[1], dz_m: d[2] };
      }
    } else {
      if (!object.id) return;
      measure.picks.push({ point: body.point_m ?? null, object });
      if (measure.picks.length === 2) {
        const [a, b] = measure.picks;
        try {
          const response = await api(`api/measure?a=${encodeURIComponent(a.object.id)}&b=${encodeURIComponent(b.object.id)}`,
                                     { cache: 'no-store' });
          if (!response.ok) {
            showError(`measure: ${await errorText(response)}`);
            measure.picks = [];
          } else {
            const j = await response.json();
            measure.result = { kind: 'objects', a: j.a.point_m, b: j.b.point_m, distance_m: j.distance_m,
                               dx_m: j.dx_m, dy_m: j.dy_m, dz_m: j.dz_m, error_m: j.error_m, method: j.method,
                               overlapping: j.overlapping === true, penetration_m: j.penetration_m,
                               aName: j.a.tag || j.a.id, bName: j.b.tag || j.b.id };
          }
        } catch (e) {
          showError(`measure: ${e.message}`);
          measure.picks = [];
        }
      }
    }
    hooks.measure = measure.result;
    showMeasure();
    drawOverlay();
  }

  function drawMeasure(g, aspect) {
    const cssW = overlay.clientWidth, cssH = overlay.clientHeight;
    const at = (p) => { const q = project(shown.camera, aspect, p); return q.depth > NEAR_M ? [q.x * cssW, q.y * cssH] : null; };
    const valid = (p) => Array.isArray(p) && p.length === 3 && p.every(Number.isFinite);
    const points = (measure.result ? [measure.result.a, measure.result.b] : measure.picks.map((p) => p.point)).filter(valid);
    g.fillStyle = '#ff6ec7';
    g.strokeStyle = '#ff6ec7';
    g.lineWidth = 2;
    const drawn = points.map(at);
    for (const p of drawn) if (p) { g.beginPath(); g.arc(p[0], p[1], 4, 0, 2 * Math.PI); g.fill(); }
    if (measure.result && points.length === 2 && drawn[0] && drawn[1]) {
      g.beginPath();
      g.moveTo(...drawn[0]);
      g.lineTo(...drawn[1]);
      g.stroke();
      g.font = 'bold 13px system-ui, sans-serif';
      g.textAlign = 'center';
      g.fillText(metres(measure.result.distance_m), (drawn[0][0] + drawn[1][0]) / 2, (drawn[0][1] + drawn[1][1]) / 2 - 8);
    }
  }

  // ---- the permalink ----

  // The address bar's fragment always holds the view: camera (eye, target, up, fov), section
  // (box, clip planes, plan, caps), selection (sel: its id), styling (colour_by, hide, only,
  // hl=1 for isolate). Opening it in a fresh page restores the same view. Updated at most every
  // LINK_MS (browsers limit how often history may be replaced).
  let linkTimer = 0;
  function scheduleLink() {
    if (linkTimer) return;
    linkTimer = setTimeout(() => { linkTimer = 0; writeLink(); }, LINK_MS);
  }
  function permalinkHash() {
    if (!camera) return '';
    const q = new URLSearchParams();
    q.set('eye', camera.eye.join(','));
    q.set('target', camera.target.join(','));
    q.set('up', camera.up.join(','));
    q.set('fov', String(camera.fov));
    if (section.box) q.set('box', [...section.box.min, ...section.box.max].join(','));
    for (const p of section.planes) q.append('clip', [...p.point, ...p.normal].join(','));
    if (section.planZ !== null) q.set('plan', String(section.planZ));
    if (!section.caps) q.set('caps', '0');
    if (selected) q.set('sel', selected.id);
    if (style.colourBy) q.set('colour_by', style.colourBy);
    if (style.hide) q.set('hide', style.hide);
    if (style.only) q.set('only', style.only);
    if (isolate) q.set('hl', '1');
    return `#${q.toString().replace(/%2C/gi, ',')}`;  // commas kept: a readable link
  }
  function writeLink() {
    const hash = permalinkHash();
    hooks.permalink = location.origin + location.pathname + location.search + hash;
    if (hash && hash !== location.hash) history.replaceState(null, '', location.pathname + location.search + hash);
  }

  // The view the page was opened with (its fragment), applied before the first frame: camera,
  // section and styling here; the selection (sel) is returned, to be looked up.
  function readLink() {
    const q = new URLSearchParams(location.hash.slice(1));
    const vec = (name, n) => {
      const v = (q.get(name) ?? '').split(',').map(Number);
      return v.length === n && v.every(Number.isFinite) ? v : null;
    };
    const eye = vec('eye', 3), target = vec('target', 3), up = vec('up', 3), fov = Number(q.get('fov'));
    const cam = eye && target && up && Number.isFinite(fov) && fov > 0 ? { eye, target, up, fov } : null;
    const box = vec('box', 6);
    if (box) section.box = { min: box.slice(0, 3), max: box.slice(3) };
    for (const c of q.getAll('clip')) {
      const v = c.split(',').map(Number);
      if (v.length === 6 && v.every(Number.isFinite)) section.planes.push({ point: v.slice(0, 3), normal: v.slice(3) });
    }
    const plan = Number(q.get('plan') ?? NaN);
    if (q.has('plan') && Number.isFinite(plan)) section.planZ = plan;
    section.caps = q.get('caps') !== '0';
    style.colourBy = q.get('colour_by') ?? '';
    style.hide = q.get('hide') ?? '';
    style.only = q.get('only') ?? '';
    isolate = q.get('hl') === '1';
    return { camera: cam, selection: q.get('sel') };
  }

  // ---- BCF viewpoints ----

  const CRC_TABLE = (() => {
    const t = new Uint32Array(256);
    for (let n = 0; n < 256; ++n) {
      let c = n;
      for (let k = 0; k < 8; ++k) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
      t[n] = c >>> 0;
    }
    return t;
  })();
  function crc32(bytes) {
    let c = 0xffffffff;
    for (let i = 0; i < bytes.length; ++i) c = CRC_TABLE[(c ^ bytes[i]) & 0xff] ^ (c >>> 8);
    return (c ^ 0xffffffff) >>> 0;
  }

  // A zip of `files` ([{name, bytes: Uint8Array}]), stored (method 0) with their CRC-32s: the
  // local headers and data, the central directory, its end record.
  function zipStored(files) {
    const enc = new TextEncoder();
    const now = new Date();
    const dosTime = (now.getHours() << 11) | (now.getMinutes() << 5) | (now.getSeconds() >> 1);
    const dosDate = ((now.getFullYear() - 1980) << 9) | ((now.getMonth() + 1) << 5) | now.getDate();
    const parts = [], central = [];
    let offset = 0, centralSize = 0;
    for (const f of files) {
      const name = enc.encode(f.name), crc = crc32(f.bytes), size = f.bytes.length;
      const local = new DataView(new ArrayBuffer(30));
      local.setUint32(0, 0x04034b50, true);
      local.setUint16(4, 20, true);
      local.setUint16(6, 0x0800, true);  // names are UTF-8
      local.setUint16(8, 0, true);       // stored
      local.setUint16(10, dosTime, true);
      local.setUint16(12, dosDate, true);
      local.setUint32(14, crc, true);
      local.setUint32(18, size, true);
      local.setUint32(22, size, true);
      local.setUint16(26, name.length, true);
      local.setUint16(28, 0, true);
      parts.push(local, name, f.bytes);
      const entry = new DataView(new ArrayBuffer(46));
      entry.setUint32(0, 0x02014b50, true);
      entry.setUint16(4, 20, true);
      entry.setUint16(6, 20, true);
      entry.setUint16(8, 0x0800, true);
      entry.setUint16(10, 0, true);
      entry.setUint16(12, dosTime, true);
      entry.setUint16(14, dosDate, true);
      entry.setUint32(16, crc, true);
      entry.setUint32(20, size, true);
      entry.setUint32(24, size, true);
      entry.setUint16(28, name.length, true);
      entry.setUint32(42, offset, true);  // extra, comment, disk and attributes stay 0
      central.push(entry, name);
      centralSize += 46 + name.length;
      offset += 30 + name.length + size;
    }
    const end = new DataView(new ArrayBuffer(22));
    end.setUint32(0, 0x06054b50, true);
    end.setUint16(8, files.length, true);
    end.setUint16(10, files.length, true);
    end.setUint32(12, centralSize, true);
    end.setUint32(16, offset, true);
    return new Blob([...parts, ...central, end], { type: 'application/octet-stream' });
  }

  // The files of a zip (a Map of name to Uint8Array), from its central directory; stored and
  // deflated entries (DecompressionStream 'deflate-raw').
  async function unzip(buffer) {
    const bytes = new Uint8Array(buffer), dv = new DataView(buffer);
    let eocd = -1;
    for (let i = bytes.length - 22; i >= Math.max(0, bytes.length - 22 - 65535); --i)
      if (dv.getUint32(i, true) === 0x06054b50) { eocd = i; break; }
    if (eocd < 0) throw new Error('not a zip file (no end of central directory)');
    const count = dv.getUint16(eocd + 10, true);
    let p = dv.getUint32(eocd + 16, true);
    const files = new Map(), dec = new TextDecoder();
    for (let i = 0; i < count; ++i) {
      if (dv.getUint32(p, true) !== 0x02014b50) throw new Error('a bad central directory entry');
      const method = dv.getUint16(p + 10, true), csize = dv.getUint32(p + 20, true);
      const nameLen = dv.getUint16(p + 28, true), extraLen = dv.getUint16(p + 30, true);
      const commentLen = dv.getUint16(p + 32, true), local = dv.getUint32(p + 42, true);
      const name = dec.decode(bytes.subarray(p + 46, p + 46 + nameLen));
      const start = local + 30 + dv.getUint16(local + 26, true) + dv.getUint16(local + 28, true);
      const data = bytes.subarray(start, start + csize);
      if (method === 0) files.set(name, data);
      else if (method === 8) {
        const stream = new Blob([data]).stream().pipeThrough(new DecompressionStream('deflate-raw'));
        files.set(name, new Uint8Array(await new Response(stream).arrayBuffer()));
      }
      p += 46 + nameLen + extraLen + commentLen;
    }
    return files;
  }

  const xmlEscape = (s) => String(s).replace(/[<>&"']/g, (c) => ({ '<': '&lt;', '>': '&gt;', '&': '&amp;', '"': '&quot;', "'": '&apos;' }[c]));
  const xyz = (tag, v) => `<${tag}><X>${v[0]}</X><Y>${v[1]}</Y><Z>${v[2]}</Z></${tag}>`;

  // The view's clipping as BCF planes (Direction points into the removed side): the clip planes,
  // then a box as six planes.
  function bcfPlanes() {
    const planes = allPlanes().map((p) => ({ location: p.point, direction: normalize(p.normal) }));
    if (section.box) for (let f = 0; f < 6; ++f) {
      const { centre, normal } = boxFace(section.box, f);
      planes.push({ location: centre, direction: normal });
    }
    return planes;
  }

  // Saves the view as a BCF 2.1 file: bcf.version, one topic (markup.bcf, viewpoint.bcfv and a
  // PNG still of the view as snapshot.png), downloaded as <title>.bcf.
  async function saveViewpoint() {
    if (!camera) return;
    const title = document.getElementById('bcf-title').value.trim() || 'plantview viewpoint';
    const topic = crypto.randomUUID(), viewpoint = crypto.randomUUID();
    const { w, h } = frameSize();
    let snapshot = null;
    try {
      const response = await api(`api/frame?${viewParams(camera, w, h)}&format=png&mode=still`, { cache: 'no-store' });
      if (response.ok) snapshot = new Uint8Array(await response.arrayBuffer());
      else showError(`viewpoint snapshot: ${await errorText(response)}`);
    } catch (e) {
      showError(`viewpoint snapshot: ${e.message}`);
    }
    const { forward } = viewBasis(camera);
    const head = '<?xml version="1.0" encoding="UTF-8"?>\n';
    const xsi = 'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xmlns:xsd="http://www.w3.org/2001/XMLSchema"';
    const version = `${head}<Version VersionId="2.1" ${xsi}><DetailedVersion>2.1</DetailedVersion></Version>\n`;
    const markup = `${head}<Markup ${xsi}>\n` +
      `  <Topic Guid="${topic}" TopicType="Issue" TopicStatus="Open">\n` +
      `    <Title>${xmlEscape(title)}</Title>\n` +
      `    <CreationDate>${new Date().toISOString()}</CreationDate>\n` +
      '    <CreationAuthor>plantview</CreationAuthor>\n' +
      '  </Topic>\n' +
      `  <Viewpoints Guid="${viewpoint}"><Viewpoint>viewpoint.bcfv</Viewpoint>` +
      `${snapshot ? '<Snapshot>snapshot.png</Snapshot>' : ''}</Viewpoints>\n` +
      '</Markup>\n';
    const components = selected
      ? '    <Selection><Component><OriginatingSystem>plantview</OriginatingSystem>' +
        `<AuthoringToolId>${xmlEscape(tagOf(selected))}</AuthoringToolId></Component></Selection>\n`
      : '';
    const planes = bcfPlanes().map((p) => `    <ClippingPlane>${xyz('Location', p.location)}${xyz('Direction', p.direction)}</ClippingPlane>\n`).join('');
    const visualization = `${head}<VisualizationInfo Guid="${viewpoint}" ${xsi}>\n` +
      `  <Components>\n${components}    <Visibility DefaultVisibility="true"/>\n  </Components>\n` +
      `  <PerspectiveCamera>${xyz('CameraViewPoint', camera.eye)}${xyz('CameraDirection', forward)}` +
      `${xyz('CameraUpVector', camera.up)}<FieldOfView>${camera.fov}</FieldOfView></PerspectiveCamera>\n` +
      (planes ? `  <ClippingPlanes>\n${planes}  </ClippingPlanes>\n` : '') +
      '</VisualizationInfo>\n';
    const enc = new TextEncoder();
    const files = [{ name: 'bcf.version', bytes: enc.encode(version) },
                   { name: `${topic}/markup.bcf`, bytes: enc.encode(markup) },
                   { name: `${topic}/viewpoint.bcfv`, bytes: enc.encode(visualization) }];
    if (snapshot) files.push({ name: `${topic}/snapshot.png`, bytes: snapshot });
    const blob = zipStored(files);
    const name = `${title.replace(/[^A-Za-z0-9._-]+/g, '_').slice(0, 80) || 'viewpoint'}.bcf`;
    const url = URL.createObjectURL(blob);
    const a = document.createElement('a');
    a.href = url;
    a.download = name;
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 60000);
    const raw = new Uint8Array(await blob.arrayBuffer());
    let binary = '';
    for (let i = 0; i < raw.length; i += 0x8000) binary += String.fromCharCode(...raw.subarray(i, i + 0x8000));
    hooks.lastBcf = { name, topic, size: raw.length, base64: btoa(binary) };
  }

  // What names an object in a BCF component: its tag (its name without the leading '/' plant
  // names carry), else its id; /api/objects/ finds it again by either.
  function tagOf(object) {
    if (object.name) return object.name.replace(/^\//, '');
    return object.id;
  }

  // Opens a .bcf/.bcfzip: the first topic's first viewpoint restores the camera, clipping (six
  // axis-aligned planes forming a box become the section box, others clip planes) and the
  // selection (the first component found by /api/objects/).
  async function openViewpoint(file) {
    try {
      const files = await unzip(await file.arrayBuffer());
      const name = [...files.keys()].find((n) => n.endsWith('.bcfv'));
      if (!name) throw new Error('no viewpoint (.bcfv) in it');
      const doc = new DOMParser().parseFromString(new TextDecoder().decode(files.get(name)), 'application/xml');
      if (doc.querySelector('parsererror')) throw new Error(`${name} is not XML`);
      const vec = (parent, tag) => {
        const e = parent?.getElementsByTagName(tag)[0];
        if (!e) return null;
        const v = ['X', 'Y', 'Z'].map((k) => Number(e.getElementsByTagName(k)[0]?.textContent));
        return v.every(Number.isFinite) ? v : null;
      };
      const pc = doc.getElementsByTagName('PerspectiveCamera')[0];
      const eye = vec(pc, 'CameraViewPoint'), dir = vec(pc, 'CameraDirection'), up = vec(pc, 'CameraUpVector');
      const fov = Number(pc?.getElementsByTagName('FieldOfView')[0]?.textContent);
      const planes = [];
      for (const cp of doc.getElementsByTagName('ClippingPlane')) {
        const location = vec(cp, 'Location'), direction = vec(cp, 'Direction');
        if (location && direction && length(direction) > 0) planes.push({ point: location, normal: normalize(direction) });
      }
      const box = planesToBox(planes);
      section.box = box;
      section.planes = box ? [] : planes.slice(0, MAX_CLIP_PLANES);
      const dropped = box ? 0 : Math.max(0, planes.length - MAX_CLIP_PLANES);
      section.planZ = null;
      planCut.checked = false;
      let found = null;
      for (const c of doc.getElementsByTagName('Component')) {
        const id = c.getElementsByTagName('AuthoringToolId')[0]?.textContent?.trim();
        if (!id) continue;
        found = await findObject(id);
        if (found) break;
      }
      if (found) { hooks.lastPick = found; showPick(found); }
      select(found);
      if (eye && dir && up && length(dir) > 0) {
        endFlight();
        const d = Math.max(1, length(sub(camera.target, camera.eye)));
        placeCamera({ eye, target: add(eye, scale(normalize(dir), d)), up,
                      fov: Number.isFinite(fov) && fov > 0 ? fov : camera.fov });
      }
      filtersChanged();
      showError(dropped ? `open viewpoint: ${dropped} clipping planes left out (at most ${MAX_CLIP_PLANES})` : '');
    } catch (e) {
      showError(`open viewpoint: ${e.message}`);
    }
  }

  // Six planes, one facing each way along each axis, form a box; anything else does not.
  function planesToBox(planes) {
    if (planes.length !== 6) return null;
    const min = [null, null, null], max = [null, null, null];
    for (const p of planes) {
      const axis = p.normal.findIndex((c) => Math.abs(Math.abs(c) - 1) < 1e-9);
      if (axis < 0) return null;
      const side = p.normal[axis] > 0 ? max : min;
      if (side[axis] !== null) return null;
      side[axis] = p.point[axis];
    }
    if (min.some((v, i) => v === null || max[i] === null || v > max[i])) return null;
    return { min, max };
  }

  // An object by its tag or id (as the search finds it), or null.
  async function findObject(text) {
    const names = [text];
    if (!text.startsWith('/') && !/^[0-9]+$/.test(text)) names.push(`/${text}`);
    for (const name of names) {
      const path = name.split('/').map(encodeURIComponent).join('/');
      const response = await api(`api/objects/${path}`, { cache: 'no-store' });
      if (response.ok) return response.json();
    }
    return null;
  }

  document.getElementById('bcf-save').addEventListener('click', (e) => { e.currentTarget.blur(); saveViewpoint(); });
  const bcfOpen = document.getElementById('bcf-open');
  bcfOpen.addEventListener('change', () => {
    const file = bcfOpen.files[0];
    if (file) openViewpoint(file);
    bcfOpen.value = '';
  });

  // ---- the frame stream (/api/stream; protocol and server rules in docs/stream.md) ----
  //
  // By default the page takes its frames from a WebSocket: a view message each time the view
  // wanted changes (pump), the server renders the latest and pushes it; the page acknowledges
  // each frame once decoded (the server sends at most 2 unacknowledged). Video (h264, else vp8)
  // is decoded with WebCodecs (VideoDecoder) onto a canvas over the image, where the browser has
  // it; otherwise, and for stills (PNG), frames are images shown in the <img>. Where the upgrade
  // fails (an older server, a proxy that drops WebSockets) the page falls back to HTTP frames and
  // tries the stream again after STREAM_RETRY_MS. ?transport=http keeps to HTTP; ?codec=jpeg|h264|vp8
  // asks for that codec. The token goes in the hello message, never in the URL.
  const STREAM_RETRY_MS = 10000;
  const VIDEO_CODECS = [['h264', 'avc1.42E01F'], ['vp8', 'vp8']];  // WebCodecs names, preferred first
  const pageOptions = new URLSearchParams(location.search);
  const stream = { ws: null, opening: false, open: false, codec: null, decoder: null, needKey: true,
                   seq: 0, views: new Map(), lastSent: null, decoding: new Map(), recent: [], kbps: null };
  hooks.stream = { transport: 'http', codec: null, kbps: null, fps: null, latencyMs: null, frames: 0,
                    videoFrames: 0, fellBack: 0 };
  const videoCanvas = document.createElement('canvas');
  videoCanvas.id = 'video';
  videoCanvas.hidden = true;
  videoCanvas.setAttribute('aria-hidden', 'true');
  frame.after(videoCanvas);

  async function videoCodec() {
    const asked = pageOptions.get('codec');
    if (asked === 'jpeg' || !('VideoDecoder' in window)) return null;
    for (const [name, codec] of VIDEO_CODECS) {
      if (asked && asked !== name) continue;
      try {
        const support = await VideoDecoder.isConfigSupported({ codec, optimizeForLatency: true });
        if (support.supported) return [name, codec];
      } catch { /* not this one */ }
    }
    return null;
  }

  async function openStream() {
    if (pageOptions.get('transport') === 'http' || !('WebSocket' in window) || stream.ws) return;
    stream.opening = true;
    const video = await videoCodec();
    const base = location.pathname.replace(/[^/]*$/, '');
    const ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}${base}api/stream`,
                             ['plantview.v1']);
    ws.binaryType = 'arraybuffer';
    stream.ws = ws;
    setTimeout(() => { if (stream.ws === ws && !stream.open) ws.close(); }, 5000);  // then HTTP
    ws.onopen = () => {
      const hello = { type: 'hello', codec: video ? video[0] : 'jpeg' };
      const token = sessionStorage.getItem(TOKEN_KEY);
      if (token) hello.token = token;
      ws.send(JSON.stringify(hello));
    };
    ws.onmessage = (e) => {
      if (typeof e.data === 'string') streamText(e.data, video);
      else streamFrame(e.data);
    };
    ws.onclose = () => {
      const wasOpen = stream.open;
      Object.assign(stream, { ws: null, opening: false, open: false, lastSent: null, needKey: true });
      if (stream.decoder && stream.decoder.state !== 'closed') stream.decoder.close();
      stream.decoder = null;
      stream.decoding.clear();
      hooks.stream.transport = 'http';
      hooks.stream.fellBack += 1;
      if (!wasOpen) showError('');
      setTimeout(openStream, STREAM_RETRY_MS);
      pump();  // HTTP meanwhile
    };
  }

  function streamText(text, video) {
    let message;
    try { message = JSON.parse(text); } catch { return; }
    if (message.type === 'ready') {
      stream.codec = message.codec;
      if (video && message.codec === video[0]) {
        stream.decoder = new VideoDecoder({ output: videoShown, error: () => { stream.needKey = true; } });
        stream.decoder.configure({ codec: video[1], optimizeForLatency: true });
      }
      stream.opening = false;
      stream.open = true;
      hooks.stream.transport = 'stream';
      hooks.stream.codec = message.codec;
      pump();
    } else if (message.type === 'error') {
      failedParams = stream.views.get(message.seq)?.params ?? failedParams;
      showError(`frame: ${message.message}`);
    }
  }

  // Sends the view wanted now, unless it is the one sent last.
  function streamView(params, request) {
    const changes = showChanges && updatedFrom !== null ? `&changes=${updatedFrom}` : '';
    const key = `${params}|${request.still}|${changes}`;
    if (key === stream.lastSent && shown !== null) return;  // shown = null: redraw (a new revision)
    stream.lastSent = key;
    const query = new URLSearchParams(`${params}&quality=${request.quality}&lod=screen-space&px=${request.px}` +
                                      `&mode=${request.still ? 'still' : 'interactive'}${changes}`);
    const json = {};
    for (const [k, v] of query) {
      if (k === 'clip') (json.clip ??= []).push(v);
      else json[k] = v;
    }
    const seq = ++stream.seq;
    stream.views.set(seq, { ...request, sentMs: performance.now() });
    for (const old of stream.views.keys()) if (old < seq - 64) stream.views.delete(old);
    stream.ws.send(JSON.stringify({ type: 'view', seq, params: json }));
  }

  // A binary frame: "PVF1", a u32 (little-endian) header length, the JSON header, the payload.
  function streamFrame(buffer) {
    const bytes = new Uint8Array(buffer);
    if (bytes.length < 8 || String.fromCharCode(...bytes.subarray(0, 4)) !== 'PVF1') return;
    const length = new DataView(buffer).getUint32(4, true);
    const header = JSON.parse(new TextDecoder().decode(bytes.subarray(8, 8 + length)));
    const payload = bytes.subarray(8 + length);
    const request = stream.views.get(header.seq);
    const ack = () => stream.ws?.send(JSON.stringify({ type: 'ack', frame: header.frame }));
    if (!request) { ack(); return; }
    const shownRequest = { ...request, still: header.still === true };
    stream.recent.push({ ms: performance.now(), bytes: payload.length });
    if (header.kbps) stream.kbps = header.kbps;
    if (header.encoding === 'jpeg' || header.encoding === 'png') {
      imageShown(new Blob([payload], { type: `image/${header.encoding}` }), header, shownRequest).finally(ack);
      return;
    }
    if (!stream.decoder || stream.decoder.state !== 'configured') { ack(); return; }
    if (stream.needKey && !header.key) {
      stream.ws.send(JSON.stringify({ type: 'key' }));
      ack();
      return;
    }
    stream.needKey = false;
    stream.decoding.set(header.frame, { header, request: shownRequest, ack });
    stream.decoder.decode(new EncodedVideoChunk({ type: header.key ? 'key' : 'delta', timestamp: header.frame,
                                                  data: payload }));
  }

  async function imageShown(blob, header, request) {
    const url = URL.createObjectURL(blob);
    frame.src = url;
    try {
      await frame.decode();
    } catch {
      URL.revokeObjectURL(url);
      if (shownUrl) frame.src = shownUrl;
      return;
    }
    if (shownUrl) URL.revokeObjectURL(shownUrl);
    shownUrl = url;
    videoCanvas.hidden = true;
    streamShown(header, request);
  }

  function videoShown(picture) {
    const pending = stream.decoding.get(picture.timestamp);
    stream.decoding.delete(picture.timestamp);
    const dpr = window.devicePixelRatio || 1;
    const cw = Math.round(videoCanvas.clientWidth * dpr) || picture.displayWidth;
    const ch = Math.round(videoCanvas.clientHeight * dpr) || picture.displayHeight;
    if (videoCanvas.width !== cw || videoCanvas.height !== ch) { videoCanvas.width = cw; videoCanvas.height = ch; }
    videoCanvas.getContext('2d').drawImage(picture, 0, 0, cw, ch);
    picture.close();
    videoCanvas.hidden = false;
    if (!pending) return;
    hooks.stream.videoFrames += 1;
    pending.ack();
    streamShown(pending.header, pending.request);
  }

  function streamShown(header, request) {
    const latencyMs = performance.now() - request.sentMs;
    hooks.stream.frames += 1;
    hooks.stream.latencyMs = latencyMs;
    const headers = new Headers(header.stats ?? {});
    if (header.revision !== undefined && !headers.has('X-Plantview-Revision'))
      headers.set('X-Plantview-Revision', String(header.revision));
    frameShown(headers, request, latencyMs);
    noticeRevision(headers);  // a frame of a newer revision than shown: describe it (following imports)
  }

  // The readout's transport line: the stream's codec, bit rate, frames/s and latency (view sent
  // to frame decoded) over the last two seconds, or HTTP polling.
  function transportText() {
    if (!stream.open) return stream.opening ? 'opening the stream…' : 'HTTP frames (one request a frame)';
    const nowMs = performance.now();
    while (stream.recent.length > 1 && nowMs - stream.recent[0].ms > 2000) stream.recent.shift();
    const n = stream.recent.length;
    const spanMs = n > 1 ? nowMs - stream.recent[0].ms : 0;
    const bits = stream.recent.reduce((sum, f) => sum + 8 * f.bytes, 0);
    hooks.stream.fps = spanMs > 0 ? (n - 1) * 1000 / spanMs : null;
    hooks.stream.kbps = spanMs > 0 ? bits / spanMs : null;
    const rate = hooks.stream.kbps === null ? '–' : `${(hooks.stream.kbps / 1000).toFixed(1)} Mbit/s`;
    const fps = hooks.stream.fps === null ? '–' : `${hooks.stream.fps.toFixed(1)} fps`;
    const latency = hooks.stream.latencyMs === null ? '–' : `${Math.round(hooks.stream.latencyMs)} ms`;
    return `stream · ${stream.codec} · ${rate} · ${fps} · latency ${latency}`;
  }

  // ---- following imports ----

  const REVISION_POLL_MS = 5000;  // idle: /api/model this often (its header says the revision)
  const updateBar = document.createElement('div');
  updateBar.id = 'model-updated';
  updateBar.hidden = true;
  const updateText = document.createElement('span');
  const changesButton = document.createElement('button');
  changesButton.type = 'button';
  changesButton.title = 'Frames show what changed: added green, modified amber, removed red';
  updateBar.append(updateText, changesButton);
  document.body.append(updateBar);
  hooks.revision = null;

  // A newer revision than the one shown: describe it, say so, redraw.
  function noticeRevision(headers) {
    const r = parseInt(headers.get('X-Plantview-Revision'), 10);
    if (!Number.isFinite(r) || revision === null || r <= revision || describing) return;
    describing = true;
    const from = revision;
    api('api/model', { cache: 'no-store' })
      .then((response) => (response.ok ? response.json() : null))
      .then(async (described) => {
        if (!described || !(described.revision > revision)) return;
        // The selection as the new revision has it (moved, say), or none if it was removed: a
        // highlight of an id the revision lacks would fail every frame.
        let gone = false;
        if (selected) {
          const id = selected.id;
          const found = await api(`api/objects/${encodeURIComponent(id)}`, { cache: 'no-store' });
          if (selected && selected.id === id) {
            if (found.ok) {
              const object = await found.json();
              select(object);
              showPick(object);
            } else if (found.status === 404) {
              gone = true;
              pickSeq += 1;
              select(null);
              showPick(undefined);
            }
          }
        }
        model = described;
        revision = described.revision;
        updatedFrom = from;
        hooks.revision = revision;
        const c = described.changes ?? {};
        const count = (c.added ?? 0) + (c.removed ?? 0) + (c.modified ?? 0);
        updateText.textContent = `model updated: revision ${revision}, ` +
          `${count.toLocaleString('en-US')} object${count === 1 ? '' : 's'} changed` +
          `${described.note ? ` (${described.note})` : ''}${gone ? '; the selection is gone' : ''}`;
        changesButton.textContent = showChanges ? 'hide changes' : 'show changes';
        updateBar.hidden = false;
        shown = null;          // redraw the same view from the new revision
        failedParams = null;
        pump();
      })
      .catch(() => { /* the next answer or poll tries again */ })
      .finally(() => { describing = false; });
  }

  changesButton.addEventListener('click', () => {
    showChanges = !showChanges;
    changesButton.textContent = showChanges ? 'hide changes' : 'show changes';
    shown = null;
    failedParams = null;
    pump();
  });

  // While idle (no frame out, the camera at rest) nothing else would hear of an import.
  setInterval(() => {
    if (revision === null || inFlight || performance.now() - lastChangeMs < REVISION_POLL_MS) return;
    api('api/model', { cache: 'no-store' }).catch(() => {});
  }, REVISION_POLL_MS);

  // ---- start ----

  // Loads the model and starts from its camera (or, lacking one, a view of its bounds from the
  // south-west, above). Retries while the server is not answering.
  async function start() {
    try {
      const response = await api('api/model', { cache: 'no-store' });
      if (!response.ok) throw new Error(await errorText(response));
      model = await response.json();
      revision = model.revision ?? 0;
      hooks.revision = revision;
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
    // A permalink's view, where the page was opened with one; its selection is looked up first,
    // so that the first frame is already the view the link holds.
    const link = readLink();
    if (link.selection) {
      try {
        const object = await findObject(link.selection);
        if (object) { hooks.lastPick = object; showPick(object); select(object); }
      } catch { /* the view without its selection */ }
    }
    camera = link.camera ?? home;
    hooks.camera = camera;
    setElevationRange();
    showStyleInputs();
    hooks.section = { box: section.box, planes: allPlanes(), caps: section.caps };
    hooks.style = { ...style, isolate };
    if (section.box || section.planes.length || section.planZ !== null)
      document.getElementById('section-tool').open = true;
    if (style.colourBy || style.hide || style.only || isolate) document.getElementById('style-tool').open = true;
    writeLink();
    openStream();
    pump();  // at rest: the first frame is a still
  }

  start();
})();
