// sparsecast viewer: vanilla JS, no external requests. Talks to /ws (see messages.py).
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const ui = window.sparsecastInteraction;  // interaction.js: drag -> camera / opacity
  const view = $("view"), vctx = view.getContext("2d");
  const overlay = $("clip-overlay"), octx = overlay.getContext("2d");
  const tfc = $("tf"), tctx = tfc.getContext("2d");
  const strip = $("tf-strip"), sctx = strip.getContext("2d");
  const IDLE_MS = 150, PICK_PX = 8;
  // Clip-box handles: radius drawn and radius picked (canvas px); one colour per axis (x, y, z).
  const HANDLE_R = 6, HANDLE_PICK_PX = 10, AXIS_COLOURS = ["#ff6b6b", "#7ee787", "#79c0ff"];
  // Clip planes: one colour per row (at most hello.limits.max_clip_planes rows).
  const PLANE_COLOURS = ["#f0883e", "#d2a8ff", "#56d4dd", "#ffdf5d", "#ff7eb6", "#a5d6ff"];

  const st = {
    ws: null, hello: null, camera: null, tf: null, index: null,
    // mode and isovalues (data units), clip box (fractions of the volume box), time step;
    // label volumes: the visible ids and the colours the user changed (id -> rgba)
    mode: "dvr", iso: [], clip: null, time: 0, labelVisible: new Set(), labelColors: new Map(),
    seq: 0, frames: 0, previewFrames: 0, lastStatus: null, pendingStatus: null,
    dirty: false, preview: false, idleTimer: 0, rafQueued: false,
    cmapColors: {},
    // the camera of the frame on screen (its status's `camera`): the clip-box overlay is
    // drawn with it, so it stays on the picture while a new frame is on its way
    frameCamera: null, handlePx: [], handleInfo: [], activeHandle: -1,
    // clip planes: rows {plane: [px, py, pz, nx, ny, nz] (point in box fractions, unit
    // normal in world axes), enabled, colour}; the render message carries the enabled ones
    planes: [],
  };
  // Exposed for tests and the console.
  window.sparsecastViewer = st;

  function showError(msg) {
    const e = $("error");
    if (!msg) { e.hidden = true; e.textContent = ""; return; }
    e.hidden = false; e.textContent = msg;
  }

  function connect() {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    const ws = new WebSocket(proto + "//" + location.host + "/ws");
    ws.binaryType = "blob";
    st.ws = ws;
    ws.onmessage = (ev) => {
      if (typeof ev.data === "string") onText(JSON.parse(ev.data));
      else onFrame(ev.data);
    };
    ws.onclose = () => { $("status").textContent = "disconnected (reload the page to reconnect)"; };
  }

  function onText(msg) {
    if (msg.type === "hello") return onHello(msg);
    if (msg.type === "frame") { st.pendingStatus = msg; return; }
    if (msg.type === "speedup") {
      if (st.lastStatus && st.lastStatus.seq === msg.seq) {
        Object.assign(st.lastStatus, msg, { type: "frame" });
        showStatus(st.lastStatus);
      }
      return;
    }
    if (msg.type === "error") showError(msg.message);
  }

  function onFrame(blob) {
    const status = st.pendingStatus; st.pendingStatus = null;
    createImageBitmap(blob).then((bmp) => {
      vctx.imageSmoothingEnabled = true;
      vctx.drawImage(bmp, 0, 0, view.width, view.height);
      bmp.close && bmp.close();
      st.frames += 1;
      if (status && status.preview) st.previewFrames += 1;
      if (status) { st.lastStatus = status; showStatus(status); if (!status.preview) showError(""); }
      if (status && status.camera) { st.frameCamera = status.camera; drawOverlay(); }
    });
  }

  const f1 = (x) => (x == null ? "-" : Number(x).toFixed(1));
  function showStatus(s) {
    const sp = s.speedup == null ? "speedup: measuring when idle" :
      `speedup ${s.speedup.toFixed(1)}x over naive (${f1(s.naive_ms)} ms ${s.speedup_source})`;
    const extra = (s.mode && s.mode !== "dvr" ? " " + s.mode : "") + (st.hello && st.hello.series ? ` t=${s.time}` : "");
    $("status").textContent =
      `${s.auto ? "auto: " : ""}${s.index}${s.cell ? " cell " + s.cell : ""} ${s.width}x${s.height}${s.preview ? " preview" : ""}${extra} | ` +
      `rebuild ${s.rebuilt ? f1(s.rebuild_ms) + " ms" : "cached"} | frame ${f1(s.frame_ms)} ms | ` +
      `${(s.samples / 1e6).toFixed(2)} M samples | ${sp}`;
  }

  function onHello(h) {
    st.hello = h;
    st.camera = Object.assign({}, h.state.camera);
    // A label volume has no TF to edit: its colours are the label table's.
    st.tf = h.state.tf ? { points: h.state.tf.points.map((p) => p.slice()), colormap: h.state.tf.colormap,
                           value_range: h.state.tf.value_range.slice() } : null;
    st.index = Object.assign({}, h.state.index);
    st.mode = h.state.mode; st.iso = h.state.iso.slice(); st.time = h.state.time;
    st.clip = { box: h.state.clip.box.map((c) => c.slice()), cap: Boolean(h.state.clip.cap) };
    st.planes = [];
    for (const p of h.state.clip.planes) addPlaneRow([...p.slice(0, 3), ...unitNormal(p.slice(3))], true);
    $("tf-box").hidden = !st.tf;
    $("volume-name").textContent = `${h.volume.name} ${h.volume.dims.join("x")} ${h.volume.dtype}`;
    const cm = $("colormap"); cm.innerHTML = "";
    cm.add(new Option("(point colours)", ""));
    for (const p of h.presets) cm.add(new Option(p, p));
    cm.value = (st.tf && st.tf.colormap) || "";
    const ix = $("index"); ix.innerHTML = "";
    for (const n of h.indices) ix.add(new Option(n, n));
    ix.value = st.index.name;
    const ce = $("cell"); ce.innerHTML = "";
    ce.add(new Option("default", ""));
    for (const c of h.cells) ce.add(new Option(String(c), String(c)));
    ce.value = st.index.cell == null ? "" : String(st.index.cell);
    const md = $("mode"); md.innerHTML = "";
    for (const m of h.modes) md.add(new Option(m, m));
    $("mode-box").hidden = h.modes.length < 2;
    buildLabelTable(h.labels);
    $("time-box").hidden = !h.series;
    if (h.series) $("time").max = String(h.series.steps - 1);
    syncInputs();
    if (st.tf) drawTF();
    request(false, true);
  }

  function syncInputs() {
    if (st.tf) {
      $("range-lo").value = st.tf.value_range[0];
      $("range-hi").value = st.tf.value_range[1];
    }
    $("mode").value = st.mode;
    $("iso-row").hidden = st.mode === "dvr";
    const vr = st.hello.volume.value_range;
    $("iso").value = String(ui.sliderPos(st.iso[0], vr[0], vr[1]));
    $("iso-value").textContent = Number(st.iso[0]).toPrecision(4);
    AXES.forEach((a, j) => {
      $(`clip-${a}-lo`).value = String(Math.round(st.clip.box[0][j] * ui.SLIDER_STEPS));
      $(`clip-${a}-hi`).value = String(Math.round(st.clip.box[1][j] * ui.SLIDER_STEPS));
    });
    $("clip-cap").checked = Boolean(st.clip.cap);
    if (st.hello.series) {
      $("time").value = String(st.time);
      $("time-value").textContent = `${st.time} / ${st.hello.series.steps - 1}  ${st.hello.series.names[st.time]}`;
    }
    $("azimuth").value = st.camera.azimuth.toFixed(1);
    $("elevation").value = st.camera.elevation.toFixed(1);
    $("zoom").value = st.camera.zoom.toFixed(2);
    $("cell").disabled = !st.index.name.startsWith("grid");
    syncPlaneRows();
    drawOverlay();
  }

  // --- clip overlay: the box's edges and a handle per face, then each enabled plane's cut of
  // the volume box and its two handles, projected with the camera of the frame shown
  // (interaction.js does the maths) -------------------------------------------------------
  function drawOverlay() {
    octx.clearRect(0, 0, overlay.width, overlay.height);
    st.handlePx = []; st.handleInfo = [];
    const cam = st.frameCamera;
    if (!$("clip-show").checked || !cam || !st.clip || !st.hello) return;
    const bounds = st.hello.volume.bounds, W = overlay.width, H = overlay.height;
    const [lo, hi] = ui.clipBoxWorld(bounds, st.clip.box);
    // Perspective: cut edges at a small depth in front of the eye (a zoom can put it inside the box).
    const near = 1e-3 * Math.hypot(...[0, 1, 2].map((j) => bounds[1][j] - bounds[0][j]));
    octx.lineWidth = 1.5; octx.strokeStyle = "rgba(255, 215, 90, 0.85)";
    octx.beginPath();
    for (const [a, b] of ui.boxEdges(lo, hi)) {
      const seg = ui.clipSegment(cam, a, b, near);
      if (!seg) continue;
      const pa = ui.projectPoint(cam, seg[0], W, H), pb = ui.projectPoint(cam, seg[1], W, H);
      if (pa && pb) { octx.moveTo(pa[0], pa[1]); octx.lineTo(pb[0], pb[1]); }
    }
    octx.stroke();
    ui.faceHandles(lo, hi).forEach((f, i) => {
      const p = ui.depth(cam, f.point) > near || !cam.perspective ? ui.projectPoint(cam, f.point, W, H) : null;
      const s = p && ui.faceAxisPx(cam, bounds, st.clip.box, f.axis, f.side, W, H);
      // A face seen head-on cannot be dragged (faceDrag would ignore it): no handle, so
      // a press there orbits.
      const draggable = s && Math.hypot(s[0], s[1]) >= ui.MIN_AXIS_PX;
      st.handlePx.push(draggable ? p : null);
      if (!draggable) return;
      octx.beginPath(); octx.arc(p[0], p[1], HANDLE_R, 0, 2 * Math.PI);
      octx.fillStyle = AXIS_COLOURS[f.axis];
      octx.globalAlpha = i === st.activeHandle ? 1 : 0.75;
      octx.fill();
      octx.globalAlpha = 1; octx.strokeStyle = i === st.activeHandle ? "#fff" : "#000"; octx.lineWidth = 1.5;
      octx.stroke();
    });
    st.handleInfo = ui.faceHandles(lo, hi).map((f) => ({ kind: "face", axis: f.axis, side: f.side }));
    st.planes.forEach((row, k) => { if (row.enabled) drawPlane(cam, bounds, row, k, near); });
  }

  // One clip plane: the polygon where it cuts the volume box (filled faintly, outlined in
  // the row's colour), a stick along the normal from the centre handle (a dot: drag moves the
  // plane along its normal) to the tip handle (a square: drag tilts the normal). A normal
  // seen nearly head-on has no centre handle (planeDrag would ignore it).
  function drawPlane(cam, bounds, row, k, near) {
    const W = overlay.width, H = overlay.height, pl = row.plane;
    const vis = (p) => (!cam.perspective || ui.depth(cam, p) > near ? ui.projectPoint(cam, p, W, H) : null);
    const poly = ui.planeBoxPolygon(bounds[0], bounds[1], ui.fracToWorld(bounds, pl.slice(0, 3)), pl.slice(3));
    octx.strokeStyle = row.colour; octx.fillStyle = row.colour; octx.lineWidth = 1.5;
    const px = poly.map(vis);
    octx.beginPath();
    if (px.length && px.every(Boolean)) {
      px.forEach((p, i) => (i ? octx.lineTo(p[0], p[1]) : octx.moveTo(p[0], p[1])));
      octx.closePath();
      octx.globalAlpha = 0.12; octx.fill();
    } else {
      // Partly behind a perspective eye: the edges cut at the near depth, not filled.
      poly.forEach((a, i) => {
        const seg = ui.clipSegment(cam, a, poly[(i + 1) % poly.length], near);
        const pa = seg && ui.projectPoint(cam, seg[0], W, H), pb = seg && ui.projectPoint(cam, seg[1], W, H);
        if (pa && pb) { octx.moveTo(pa[0], pa[1]); octx.lineTo(pb[0], pb[1]); }
      });
    }
    octx.globalAlpha = 0.9; octx.stroke(); octx.globalAlpha = 1;
    const hd = ui.planeHandles(bounds, pl), pc = vis(hd.centre), pt = vis(hd.tip);
    if (pc && pt) { octx.beginPath(); octx.moveTo(pc[0], pc[1]); octx.lineTo(pt[0], pt[1]); octx.stroke(); }
    const s = pc && ui.planeAxisPx(cam, bounds, pl, W, H);
    const centre = s && Math.hypot(s[0], s[1]) >= ui.MIN_AXIS_PX ? pc : null;
    for (const [kind, p] of [["centre", centre], ["tip", pt]]) {
      const i = st.handlePx.length;
      st.handlePx.push(p); st.handleInfo.push({ kind, k });
      if (!p) continue;
      octx.beginPath();
      if (kind === "centre") octx.arc(p[0], p[1], HANDLE_R, 0, 2 * Math.PI);
      else octx.rect(p[0] - HANDLE_R + 1, p[1] - HANDLE_R + 1, 2 * HANDLE_R - 2, 2 * HANDLE_R - 2);
      octx.fillStyle = row.colour; octx.globalAlpha = i === st.activeHandle ? 1 : 0.8; octx.fill();
      octx.globalAlpha = 1; octx.strokeStyle = i === st.activeHandle ? "#fff" : "#000"; octx.lineWidth = 1.5;
      octx.stroke();
    }
  }
  // Canvas pixel of a pointer event on the view (the canvas may be drawn scaled).
  function viewXY(e) {
    const r = view.getBoundingClientRect();
    return [(e.clientX - r.left) * (view.width / r.width), (e.clientY - r.top) * (view.height / r.height)];
  }
  const handleAt = (e) => { const [x, y] = viewXY(e); return ui.pickHandle(st.handlePx, x, y, HANDLE_PICK_PX); };
  // CSS pixel (relative to the view's top-left) of handle i (x-lo, x-hi, y-lo, ..., z-hi, then
  // per enabled plane its centre and its tip), or null: for tests.
  st.handlePixel = (i) => {
    const p = st.handlePx[i], r = view.getBoundingClientRect();
    return p ? [p[0] * r.width / view.width, p[1] * r.height / view.height] : null;
  };
  // Index into handlePx of plane row k's "centre" or "tip" handle, or -1 (disabled row): for tests.
  st.planeHandleIndex = (k, kind) => st.handleInfo.findIndex((h) => h.k === k && h.kind === kind);

  // --- requests: coalesced per animation frame; previews while interacting ----------
  function request(preview, all) {
    st.dirty = true;
    st.preview = preview;
    st.sendAll = st.sendAll || !!all;
    if (!st.rafQueued) { st.rafQueued = true; requestAnimationFrame(flush); }
    clearTimeout(st.idleTimer);
    if (preview) st.idleTimer = setTimeout(() => request(false), IDLE_MS);
  }

  function flush() {
    st.rafQueued = false;
    if (!st.dirty || !st.ws || st.ws.readyState !== 1) return;
    st.dirty = false;
    st.seq += 1;
    const msg = {
      type: "render", seq: st.seq, preview: st.preview,
      width: view.width, height: view.height,
      camera: st.camera, index: st.index, mode: st.mode, iso: st.iso,
      clip: ui.clipMessage(st.clip.box, st.planes, st.clip.cap, maxPlanes()),
    };
    if (st.tf) msg.tf = st.tf;
    if (st.hello.series) msg.time = st.time;
    if (st.hello.labels) {
      // Only the colours the user changed travel: a table of thousands of ids would not fit a message.
      msg.labels = { visible: [...st.labelVisible], colors: [...st.labelColors].map(([i, c]) => [i, ...c]),
                     smooth: st.labelSmooth };
    }
    st.sendAll = false;
    st.ws.send(JSON.stringify(msg));
  }

  // --- orbit / zoom -------------------------------------------------------------------
  let drag = null, hdrag = null;
  // Left drag orbits; shift-drag, right or middle drag pans; a left press on a clip-box
  // handle drags that face instead, on a plane's centre handle moves that plane along its
  // normal, on its tip handle tilts the normal.
  view.addEventListener("contextmenu", (e) => e.preventDefault());
  view.addEventListener("pointerdown", (e) => {
    const hit = e.button === 0 && !e.shiftKey ? handleAt(e) : -1;
    if (hit >= 0) {
      const [x, y] = viewXY(e);
      // Face handles come in faceHandles' order (x-lo, x-hi, ..., z-hi), then the planes'. The
      // drag maps pointer motion with the box, plane and camera it started from (moving back
      // puts the face or plane back).
      const info = st.handleInfo[hit];
      hdrag = Object.assign({ x, y, box: st.clip.box.map((c) => c.slice()), cam: st.frameCamera }, info,
                            info.kind === "face" ? {} : { plane: st.planes[info.k].plane.slice() });
      if (info.kind !== "face") st.currentPlane = info.k;  // the plane the keys move
      st.activeHandle = hit;
      view.setPointerCapture(e.pointerId);
      view.classList.add("dragging-handle");
      drawOverlay();
      return;
    }
    const pan = st.camera.pan || [0, 0];
    drag = { x: e.clientX, y: e.clientY, az: st.camera.azimuth, el: st.camera.elevation,
             pan: e.shiftKey || e.button !== 0, px: pan[0], py: pan[1] };
    view.setPointerCapture(e.pointerId);
    view.classList.add("dragging");
  });
  view.addEventListener("pointermove", (e) => {
    if (hdrag) {
      const [x, y] = viewXY(e);
      const b = st.hello.volume.bounds, dx = x - hdrag.x, dy = y - hdrag.y, W = view.width, H = view.height;
      if (hdrag.kind === "face") {
        const [lo, hi] = ui.faceDrag(hdrag.cam, b, hdrag.box, hdrag.axis, hdrag.side, dx, dy, W, H);
        st.clip.box[0][hdrag.axis] = lo; st.clip.box[1][hdrag.axis] = hi;
      } else {
        const move = hdrag.kind === "centre" ? ui.planeDrag : ui.planeTilt;
        st.planes[hdrag.k].plane = move(hdrag.cam, b, hdrag.plane, dx, dy, W, H);
      }
      // Like the clip sliders: preview frames while dragging; a clip change never rebuilds the index.
      syncInputs();
      request(true);
      return;
    }
    if (!drag) { view.classList.toggle("on-handle", handleAt(e) >= 0); return; }
    if (drag.pan) {
      // One view height is two bounding-sphere radii divided by the zoom.
      const k = 2 / (view.clientHeight || 512) / st.camera.zoom;
      const clamp = (v) => Math.max(-5, Math.min(5, v));
      st.camera.pan = [clamp(drag.px - (e.clientX - drag.x) * k), clamp(drag.py + (e.clientY - drag.y) * k)];
    } else {
      const ang = ui.orbitDrag(drag.az, drag.el, e.clientX - drag.x, e.clientY - drag.y);
      st.camera.azimuth = ang.azimuth;
      st.camera.elevation = ang.elevation;
    }
    syncInputs();
    request(true);
  });
  const endDrag = () => {
    if (hdrag) {
      // A plane drag that stopped on the box's surface: its point moves (within the plane) back
      // inside, so the next drag along the normal can go on.
      if (hdrag.kind !== "face" && st.planes[hdrag.k]) {
        st.planes[hdrag.k].plane = ui.planeRecentre(st.hello.volume.bounds, st.planes[hdrag.k].plane);
      }
      hdrag = null; st.activeHandle = -1; view.classList.remove("dragging-handle"); syncInputs(); request(false);
    }
    if (drag) { drag = null; view.classList.remove("dragging"); request(false); }
  };
  view.addEventListener("pointerup", endDrag);
  view.addEventListener("pointercancel", endDrag);
  view.addEventListener("wheel", (e) => {
    e.preventDefault();
    st.camera.zoom = Math.max(0.05, Math.min(50, st.camera.zoom * Math.exp(-e.deltaY * 0.0015)));
    syncInputs();
    request(true);
  }, { passive: false });

  // Keys over the page (not while typing into a field): arrows orbit (shift: finer), + / -
  // zoom, [ / ] move the current plane (the last one added or dragged) along its normal,
  // f flips it. Held keys repeat as preview frames; the release renders in full.
  let keyed = false;
  document.addEventListener("keydown", (e) => {
    const t = e.target;
    if (!st.hello || e.ctrlKey || e.metaKey || e.altKey ||
        (t && (t.isContentEditable || ["INPUT", "TEXTAREA", "SELECT"].includes(t.tagName)))) return;
    const act = ui.keyAction(e.key, e.shiftKey, st.camera);
    if (!act) return;
    const k = Math.min(st.currentPlane ?? st.planes.length - 1, st.planes.length - 1);
    if (act.camera) Object.assign(st.camera, act.camera);
    else if (k < 0) return;  // a plane key with no plane
    else if (act.flip) st.planes[k].plane = [...st.planes[k].plane.slice(0, 3), ...st.planes[k].plane.slice(3).map((v) => (v === 0 ? 0 : -v))];
    else st.planes[k].plane = ui.planeNudge(st.hello.volume.bounds, st.planes[k].plane, act.plane);
    e.preventDefault();
    keyed = true;
    syncInputs();
    request(true);
  });
  document.addEventListener("keyup", () => { if (keyed) { keyed = false; request(false); } });

  for (const id of ["azimuth", "elevation", "zoom"]) {
    $(id).addEventListener("change", () => {
      const v = parseFloat($(id).value);
      if (!isFinite(v)) return syncInputs();
      if (id === "elevation") st.camera.elevation = Math.max(-90, Math.min(90, v));
      else if (id === "zoom") st.camera.zoom = Math.max(0.05, Math.min(50, v));
      else st.camera.azimuth = ((v % 360) + 360) % 360;
      syncInputs(); request(false);
    });
  }

  // --- TF editor ----------------------------------------------------------------------
  const PAD = 6;
  const toPx = (p) => [PAD + p[0] * (tfc.width - 2 * PAD), tfc.height - PAD - p[4] * (tfc.height - 2 * PAD)];
  const fromPx = (x, y) => [
    Math.max(0, Math.min(1, (x - PAD) / (tfc.width - 2 * PAD))),
    ui.opacityAt(y, tfc.height, PAD),
  ];

  function interpColour(x) {
    const pts = st.tf.points;
    if (x <= pts[0][0]) return pts[0].slice(1, 4);
    for (let i = 1; i < pts.length; i++) {
      if (x <= pts[i][0]) {
        const a = pts[i - 1], b = pts[i], t = b[0] > a[0] ? (x - a[0]) / (b[0] - a[0]) : 0;
        return [1, 2, 3].map((c) => a[c] + t * (b[c] - a[c]));
      }
    }
    return pts[pts.length - 1].slice(1, 4);
  }

  function drawTF() {
    if (!st.tf) return;
    const w = tfc.width, h = tfc.height;
    tctx.clearRect(0, 0, w, h);
    const hist = st.hello.histogram.counts, vr = st.hello.histogram.range, tr = st.tf.value_range;
    const logc = hist.map((c) => Math.log1p(c)); const top = Math.max(...logc) || 1;
    tctx.fillStyle = "#30363d";
    // Histogram bins are over the volume range; the editor's x axis is the TF range.
    for (let i = 0; i < hist.length; i++) {
      const v0 = vr[0] + (i / hist.length) * (vr[1] - vr[0]), v1 = vr[0] + ((i + 1) / hist.length) * (vr[1] - vr[0]);
      const x0 = PAD + ((v0 - tr[0]) / (tr[1] - tr[0])) * (w - 2 * PAD), x1 = PAD + ((v1 - tr[0]) / (tr[1] - tr[0])) * (w - 2 * PAD);
      const bh = (logc[i] / top) * (h - 2 * PAD);
      tctx.fillRect(x0, h - PAD - bh, Math.max(1, x1 - x0 - 0.5), bh);
    }
    const pts = st.tf.points;
    tctx.strokeStyle = "#e6edf3"; tctx.lineWidth = 1.5; tctx.beginPath();
    pts.forEach((p, i) => { const [x, y] = toPx(p); i ? tctx.lineTo(x, y) : tctx.moveTo(x, y); });
    tctx.stroke();
    for (const p of pts) {
      const [x, y] = toPx(p);
      tctx.fillStyle = `rgb(${p[1] * 255},${p[2] * 255},${p[3] * 255})`;
      tctx.strokeStyle = "#fff";
      tctx.beginPath(); tctx.arc(x, y, 5, 0, 2 * Math.PI); tctx.fill(); tctx.stroke();
    }
    // Colour strip: the colour map when one is chosen (as the server applies it), else point colours.
    const sw = strip.width, cmap = st.tf.colormap && st.hello.colormaps ? st.hello.colormaps[st.tf.colormap] : null;
    for (let i = 0; i < sw; i++) {
      const x = (i + 0.5) / sw;
      const c = cmap ? cmap[Math.min(cmap.length - 1, Math.floor(x * cmap.length))] : interpColour(x);
      sctx.fillStyle = `rgb(${c[0] * 255},${c[1] * 255},${c[2] * 255})`;
      sctx.fillRect(i, 0, 1, strip.height);
    }
  }

  function pointAt(x, y) {
    let best = -1, bd = PICK_PX * PICK_PX;
    st.tf.points.forEach((p, i) => {
      const [px, py] = toPx(p); const d = (px - x) ** 2 + (py - y) ** 2;
      if (d <= bd) { bd = d; best = i; }
    });
    return best;
  }
  function canvasXY(e) {
    const r = tfc.getBoundingClientRect();
    return [(e.clientX - r.left) * (tfc.width / r.width), (e.clientY - r.top) * (tfc.height / r.height)];
  }
  // Pixel position (CSS px, relative to the editor's top-left) of point i: for tests.
  st.pointPixel = (i) => {
    const r = tfc.getBoundingClientRect(); const [x, y] = toPx(st.tf.points[i]);
    return [x * r.width / tfc.width, y * r.height / tfc.height];
  };

  function sortPoints(keep) {
    const p = st.tf.points[keep];
    st.tf.points.sort((a, b) => a[0] - b[0]);
    return st.tf.points.indexOf(p);
  }

  let tdrag = -1;
  tfc.addEventListener("pointerdown", (e) => {
    if (e.button !== 0 || !st.hello || !st.tf) return;
    const [x, y] = canvasXY(e);
    let i = pointAt(x, y);
    if (i < 0) {
      if (st.tf.points.length >= st.hello.limits.max_points) return showError("too many TF points");
      const [nx, na] = fromPx(x, y);
      const c = interpColour(nx);
      st.tf.points.push([nx, c[0], c[1], c[2], na]);
      i = sortPoints(st.tf.points.length - 1);
      drawTF(); request(true);
    }
    tdrag = i;
    tfc.setPointerCapture(e.pointerId);
  });
  tfc.addEventListener("pointermove", (e) => {
    if (tdrag < 0) return;
    const [x, y] = canvasXY(e);
    const [nx, na] = fromPx(x, y);
    const p = st.tf.points[tdrag];
    p[0] = nx; p[4] = na;
    tdrag = sortPoints(tdrag);
    drawTF(); request(true);
  });
  const endT = () => { if (tdrag >= 0) { tdrag = -1; request(false); } };
  tfc.addEventListener("pointerup", endT);
  tfc.addEventListener("pointercancel", endT);
  function removeAt(e) {
    e.preventDefault();
    const [x, y] = canvasXY(e);
    const i = pointAt(x, y);
    if (i >= 0 && st.tf.points.length > 2) { st.tf.points.splice(i, 1); drawTF(); request(false); }
  }
  tfc.addEventListener("dblclick", removeAt);
  tfc.addEventListener("contextmenu", removeAt);

  $("colormap").addEventListener("change", () => {
    st.tf.colormap = $("colormap").value || null;
    drawTF(); request(false);
  });
  function rangeChanged() {
    const lo = parseFloat($("range-lo").value), hi = parseFloat($("range-hi").value);
    if (!(isFinite(lo) && isFinite(hi) && lo < hi)) { showError("range: expected numbers lo < hi"); return syncInputs(); }
    st.tf.value_range = [lo, hi]; drawTF(); request(false);
  }
  $("range-lo").addEventListener("change", rangeChanged);
  $("range-hi").addEventListener("change", rangeChanged);
  $("range-reset").addEventListener("click", () => {
    st.tf.value_range = st.hello.volume.value_range.slice(); syncInputs(); drawTF(); request(false);
  });
  $("index").addEventListener("change", () => {
    st.index.name = $("index").value;
    if (!st.index.name.startsWith("grid")) st.index.cell = null;
    syncInputs(); request(false);
  });
  $("cell").addEventListener("change", () => {
    const v = $("cell").value; st.index.cell = v ? parseInt(v, 10) : null; request(false);
  });

  // --- render mode and isovalue ---------------------------------------------------------
  const AXES = ["x", "y", "z"];
  $("mode").addEventListener("change", () => { st.mode = $("mode").value; syncInputs(); request(false); });
  // Sliders: "input" while dragging (preview frames), "change" on release (a full frame).
  function onSlide(el, apply) {
    el.addEventListener("input", () => { apply(); syncInputs(); request(true); });
    el.addEventListener("change", () => { apply(); syncInputs(); request(false); });
  }
  onSlide($("iso"), () => {
    const vr = st.hello.volume.value_range;
    st.iso[0] = ui.sliderValue(parseInt($("iso").value, 10), vr[0], vr[1]);
  });

  // --- clip box: two sliders per axis, fractions of the volume box ----------------------
  AXES.forEach((a, j) => {
    for (const side of ["lo", "hi"]) {
      onSlide($(`clip-${a}-${side}`), () => {
        const lo = parseInt($(`clip-${a}-lo`).value, 10) / ui.SLIDER_STEPS;
        const hi = parseInt($(`clip-${a}-hi`).value, 10) / ui.SLIDER_STEPS;
        [st.clip.box[0][j], st.clip.box[1][j]] = ui.clipPair(lo, hi, side);
      });
    }
  });
  $("clip-cap").addEventListener("change", () => { st.clip.cap = $("clip-cap").checked; request(false); });
  $("clip-show").addEventListener("change", drawOverlay);
  $("clip-reset").addEventListener("click", () => {
    st.clip = { box: [[0, 0, 0], [1, 1, 1]], cap: st.clip.cap }; st.planes = []; st.currentPlane = undefined;
    buildPlaneRows(); syncInputs(); request(false);
  });

  // --- clip planes: a row per plane (enable, normal, flip, remove, offset along the normal) --
  const maxPlanes = () => (st.hello && st.hello.limits.max_clip_planes) || 6;
  const unitNormal = (n) => { const l = Math.hypot(...n); return n.map((v) => v / l); };
  const fmt = (v) => (Math.abs(v) < 5e-4 ? 0 : v).toFixed(3);  // no "-0.000"
  function addPlaneRow(plane, enabled) {
    const used = new Set(st.planes.map((r) => r.colour));
    const colour = PLANE_COLOURS.find((c) => !used.has(c)) || PLANE_COLOURS[st.planes.length % PLANE_COLOURS.length];
    st.planes.push({ plane, enabled, colour });
    st.currentPlane = st.planes.length - 1;  // the plane the keys move
  }
  function buildPlaneRows() {
    const list = $("plane-list"); list.innerHTML = "";
    st.planes.forEach((row, k) => {
      const div = document.createElement("div"); div.className = "plane-row"; div.style.borderLeftColor = row.colour;
      const mk = (tag, props) => Object.assign(document.createElement(tag), props);
      const on = mk("input", { type: "checkbox", className: "plane-on", checked: row.enabled, title: "clip with this plane" });
      on.addEventListener("change", () => { row.enabled = on.checked; syncInputs(); request(false); });
      const normal = mk("input", { type: "text", className: "plane-normal", spellcheck: false,
                                   title: "normal nx, ny, nz (world axes; the side it points to is kept)" });
      normal.addEventListener("change", () => {
        const v = normal.value.split(/[\s,]+/).filter(Boolean).map(Number);
        if (v.length !== 3 || !v.every(isFinite) || !v.some((c) => c !== 0)) {
          showError("plane normal: expected three numbers nx, ny, nz, not all 0"); return syncInputs();
        }
        // The plane turns about its point (which stays inside the box).
        row.plane = [...row.plane.slice(0, 3), ...unitNormal(v)]; syncInputs(); request(false);
      });
      const flip = mk("button", { type: "button", className: "plane-flip", textContent: "flip",
                                  title: "keep the other side (negate the normal)" });
      flip.addEventListener("click", () => {
        row.plane = [...row.plane.slice(0, 3), ...row.plane.slice(3).map((v) => (v === 0 ? 0 : -v))];
        syncInputs(); request(false);
      });
      const del = mk("button", { type: "button", className: "plane-remove", textContent: "remove" });
      del.addEventListener("click", () => { st.planes.splice(k, 1); st.currentPlane = undefined; buildPlaneRows(); syncInputs(); request(false); });
      const slider = mk("input", { type: "range", className: "plane-offset", min: "0", max: String(ui.SLIDER_STEPS),
                                   step: "1", title: "offset along the normal" });
      const value = mk("input", { type: "number", className: "plane-offset-value", step: "any",
                                  title: "offset along the normal from the volume's centre (world units)" });
      const b = () => st.hello.volume.bounds;
      const setOffset = (s) => { row.plane = ui.planeAtOffset(b(), row.plane, s); };
      const fromSlider = () => {
        const h = ui.planeHalfRange(b(), row.plane.slice(3));
        setOffset(ui.sliderValue(parseInt(slider.value, 10), -h, h));
      };
      slider.addEventListener("input", () => { fromSlider(); syncInputs(); request(true); });
      slider.addEventListener("change", () => { fromSlider(); syncInputs(); request(false); });
      value.addEventListener("change", () => {
        const s = parseFloat(value.value);
        if (!isFinite(s)) return syncInputs();
        setOffset(s); syncInputs(); request(false);
      });
      const line1 = mk("div", { className: "plane-line" }), line2 = mk("div", { className: "plane-line" });
      line1.append(on, mk("span", { className: "plane-label", textContent: `${k + 1} normal` }), normal, flip, del);
      line2.append(mk("span", { className: "plane-label", textContent: "offset" }), slider, value);
      div.append(line1, line2);
      list.appendChild(div);
    });
  }
  // Row values from the state (the text being typed into is left alone).
  function syncPlaneRows() {
    const rows = $("plane-list").querySelectorAll(".plane-row");
    if (rows.length !== st.planes.length) return buildPlaneRows(), syncPlaneRows();
    const b = st.hello.volume.bounds;
    st.planes.forEach((row, k) => {
      const el = rows[k], n = row.plane.slice(3), h = ui.planeHalfRange(b, n), s = ui.planeOffset(b, row.plane);
      el.querySelector(".plane-on").checked = row.enabled;
      el.classList.toggle("disabled", !row.enabled);
      const normal = el.querySelector(".plane-normal"), value = el.querySelector(".plane-offset-value");
      if (document.activeElement !== normal) normal.value = n.map(fmt).join(", ");
      el.querySelector(".plane-offset").value = String(ui.sliderPos(s, -h, h));
      if (document.activeElement !== value) value.value = String(Number(s.toPrecision(6)));
      value.min = String(-h); value.max = String(h);
    });
    const full = st.planes.length >= maxPlanes();
    $("plane-add").disabled = full;
    $("plane-count").textContent = `${st.planes.length} / ${maxPlanes()}`;
  }
  $("plane-add").addEventListener("click", () => {
    if (st.planes.length >= maxPlanes()) return;
    addPlaneRow(ui.newPlane(st.frameCamera, st.hello.volume.bounds, st.clip.box), true);
    buildPlaneRows(); syncInputs(); request(false);
  });

  // --- time ---------------------------------------------------------------------------------
  onSlide($("time"), () => { st.time = parseInt($("time").value, 10); });

  // --- label table: a checkbox, a colour swatch (a picker) and the voxel count per id ------
  const hex = (c) => "#" + c.slice(0, 3).map((v) => Math.round(v * 255).toString(16).padStart(2, "0")).join("");
  const unhex = (s) => [1, 3, 5].map((i) => parseInt(s.slice(i, i + 2), 16) / 255);
  function buildLabelTable(labels) {
    $("labels-box").hidden = !labels;
    const body = $("label-table").tBodies[0]; body.innerHTML = "";
    if (!labels) return;
    st.labelVisible = new Set(labels.visible);
    st.labelSmooth = Boolean(labels.smooth); $("labels-smooth").checked = st.labelSmooth;
    labels.ids.forEach((id, k) => {
      const tr = body.insertRow();
      const box = document.createElement("input");
      box.type = "checkbox"; box.checked = st.labelVisible.has(id); box.dataset.id = String(id);
      box.addEventListener("change", () => {
        if (box.checked) st.labelVisible.add(id); else st.labelVisible.delete(id);
        request(false);
      });
      tr.insertCell().appendChild(box);
      tr.insertCell().textContent = String(id);
      const pick = document.createElement("input");
      pick.type = "color"; pick.value = hex(labels.colors[k]); pick.title = `colour of label ${id}`;
      const alpha = labels.colors[k][3] > 0 ? labels.colors[k][3] : 1;
      const recolour = (preview) => { st.labelColors.set(id, [...unhex(pick.value), alpha]); request(preview); };
      pick.addEventListener("input", () => recolour(true));
      pick.addEventListener("change", () => recolour(false));
      tr.insertCell().appendChild(pick);
      const n = tr.insertCell(); n.className = "num"; n.textContent = labels.counts[k].toLocaleString("en");
    });
  }
  function setAllLabels(on) {
    st.labelVisible = new Set(on ? st.hello.labels.ids : []);
    for (const b of $("label-table").querySelectorAll("input[type=checkbox]")) b.checked = on;
    request(false);
  }
  $("labels-smooth").addEventListener("change", () => { st.labelSmooth = $("labels-smooth").checked; request(false); });
  $("labels-all").addEventListener("click", () => setAllLabels(true));
  $("labels-none").addEventListener("click", () => setAllLabels(false));

  connect();
})();
