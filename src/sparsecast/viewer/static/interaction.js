// sparsecast viewer: pure mappings from pointer motion and sliders to camera, TF, clip and isovalues,
// the projection of the clip box onto the image (its drag handles), and the clip planes (their
// cut of the box, centre and normal handles, drags and offsets).
// No DOM here, so tests can run it under node (tests/viewer/test_interaction.py).
"use strict";
(function (root) {
  // Degrees of orbit per CSS pixel of drag.
  const ORBIT_DEG_PER_PX = 0.4;
  // An opacity point dragged within this many pixels of the editor's floor is set to
  // exactly 0: a TF that is 0 (not 0.004) below a value is what lets the renderer
  // classify that range as empty space and skip it.
  const SNAP_PX = 4;

  // Camera angles after dragging (dx, dy) CSS px from a drag that started at (az, el).
  // The surface under the cursor follows the mouse on both axes: with sparsecast's
  // orbit convention (camera.py) a larger azimuth moves the front surface right on
  // screen and a larger elevation moves it down (screen y grows downwards).
  function orbitDrag(az, el, dx, dy) {
    return {
      azimuth: (((az + dx * ORBIT_DEG_PER_PX) % 360) + 360) % 360,
      elevation: Math.max(-89.9, Math.min(89.9, el + dy * ORBIT_DEG_PER_PX)),
    };
  }

  // Opacity in [0, 1] for pointer height y (canvas px) in an editor of `height` px
  // with `pad` px of padding; near the floor it snaps to exactly 0.
  function opacityAt(y, height, pad) {
    const span = height - 2 * pad, up = height - pad - y;
    if (up <= SNAP_PX) return 0;
    return Math.max(0, Math.min(1, up / span));
  }

  // Range sliders have SLIDER_STEPS integer positions; these map them onto [lo, hi].
  const SLIDER_STEPS = 1000;
  function sliderValue(pos, lo, hi) {
    return lo + (Math.max(0, Math.min(SLIDER_STEPS, pos)) / SLIDER_STEPS) * (hi - lo);
  }
  function sliderPos(v, lo, hi) {
    if (!(hi > lo)) return 0;
    return Math.round(Math.max(0, Math.min(1, (v - lo) / (hi - lo))) * SLIDER_STEPS);
  }

  // Clip interval [lo, hi] of one axis after one of its sliders moved: the slider that
  // moved wins and pushes the other along, so lo <= hi always holds (the server
  // refuses lo > hi).
  function clipPair(lo, hi, moved) {
    if (lo <= hi) return [lo, hi];
    return moved === "lo" ? [lo, lo] : [hi, hi];
  }

  // --- clip-box overlay: world points -> image pixels with the frame's camera -------------
  // `cam` is a frame status's `camera` (session.frame_camera, i.e. Camera.ray_params by
  // name): eye, forward (unit), right and up (the image plane's half extents). The ray of
  // normalised screen point (u, v) in [-1, 1] (v up) starts at eye + u right + v up along
  // forward (orthographic) or at eye along forward + u right + v up (perspective); pixel
  // (col, row) has u = (col + 0.5) / width * 2 - 1, v = 1 - (row + 0.5) / height * 2
  // (kernels/camera.py). The functions below invert that map.
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const lerp3 = (a, b, t) => [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])];

  // Depth of world point p along the view direction (world units from the eye).
  function depth(cam, p) { return dot(sub(p, cam.eye), cam.forward); }

  // Image position [x, y] (pixels, origin at the image's top-left corner, y down; pixel
  // (col, row) covers [col, col + 1) x [row, row + 1)) of world point p in a width x height
  // image, or null for a perspective camera when p is not in front of the eye.
  function projectPoint(cam, p, width, height) {
    const d = sub(p, cam.eye);
    let s = 1;
    if (cam.perspective) {
      const z = dot(d, cam.forward);
      if (!(z > 0)) return null;
      s = 1 / z;  // right and up are orthogonal to forward: the ray reaches p at t = z
    }
    const u = (dot(d, cam.right) / dot(cam.right, cam.right)) * s;
    const v = (dot(d, cam.up) / dot(cam.up, cam.up)) * s;
    return [(u + 1) * 0.5 * width, (1 - v) * 0.5 * height];
  }

  // Segment a-b cut to the part in front of a perspective camera (depth >= near), or null.
  function clipSegment(cam, a, b, near) {
    if (!cam.perspective) return [a, b];
    const za = depth(cam, a), zb = depth(cam, b);
    if (za < near && zb < near) return null;
    if (za >= near && zb >= near) return [a, b];
    const m = lerp3(a, b, (near - za) / (zb - za));
    return za < near ? [m, b] : [a, m];
  }

  // World corners [lo, hi] of clip box `box` ([[x0, y0, z0], [x1, y1, z1]], fractions of
  // the volume box) inside `bounds` (the volume's world box, hello.volume.bounds): the
  // same map as session.clip_world.
  function clipBoxWorld(bounds, box) {
    return box.map((f) => f.map((t, j) => bounds[0][j] + t * (bounds[1][j] - bounds[0][j])));
  }

  // The 12 edges of the world box [lo, hi], each [a, b]: corner k has x from bit 0, y
  // from bit 1, z from bit 2; an edge joins corners one bit apart.
  function boxEdges(lo, hi) {
    const corner = (k) => [0, 1, 2].map((j) => ((k >> j) & 1 ? hi[j] : lo[j]));
    const out = [];
    for (let k = 0; k < 8; k++) for (let j = 0; j < 3; j++) if (!((k >> j) & 1)) out.push([corner(k), corner(k | (1 << j))]);
    return out;
  }

  // The 6 face handles of the world box [lo, hi]: {axis, side ("lo" / "hi"), point}, the
  // point at the face's centre, in the order x-lo, x-hi, y-lo, y-hi, z-lo, z-hi.
  function faceHandles(lo, hi) {
    const out = [];
    for (let j = 0; j < 3; j++) {
      for (const side of ["lo", "hi"]) {
        const point = [0, 1, 2].map((i) => (i === j ? (side === "lo" ? lo : hi)[i] : 0.5 * (lo[i] + hi[i])));
        out.push({ axis: j, side, point });
      }
    }
    return out;
  }

  // Index of the handle (image positions `pts`, null for one not shown) nearest to (x, y)
  // within `radius` pixels, or -1.
  function pickHandle(pts, x, y, radius) {
    let best = -1, bd = radius * radius;
    pts.forEach((p, i) => {
      if (!p) return;
      const d = (p[0] - x) ** 2 + (p[1] - y) ** 2;
      if (d <= bd) { bd = d; best = i; }
    });
    return best;
  }

  // A face handle whose axis spans fewer image pixels than this per whole box (the face
  // seen nearly head-on) cannot be dragged: a pixel of pointer motion would jump the face
  // across the box.
  const MIN_AXIS_PX = 8;

  // Image pixels the face of `axis` at box fraction `t` moves per unit of fraction, as a
  // vector [px, py]: the derivative of its centre's projection (perspective is not linear,
  // so a small step, not the whole box). null when the centre is behind the eye.
  function faceAxisPx(cam, bounds, box, axis, side, width, height) {
    const [lo, hi] = clipBoxWorld(bounds, box);
    const c = faceHandles(lo, hi)[2 * axis + (side === "hi" ? 1 : 0)].point;
    const h = 1e-3, ext = bounds[1][axis] - bounds[0][axis];
    const c1 = c.slice(); c1[axis] += h * ext;
    const p0 = projectPoint(cam, c, width, height), p1 = projectPoint(cam, c1, width, height);
    if (!p0 || !p1) return null;
    return [(p1[0] - p0[0]) / h, (p1[1] - p0[1]) / h];
  }

  // World ray [origin, direction] the renderer casts through image position (x, y) (the
  // forward map of projectPoint; the direction is not normalised).
  function pixelRay(cam, x, y, width, height) {
    const u = (x / width) * 2 - 1, v = 1 - (y / height) * 2;
    const off = [0, 1, 2].map((j) => u * cam.right[j] + v * cam.up[j]);
    if (cam.perspective) return [cam.eye.slice(), [0, 1, 2].map((j) => cam.forward[j] + off[j])];
    return [[0, 1, 2].map((j) => cam.eye[j] + off[j]), cam.forward.slice()];
  }

  // Clip interval [lo, hi] of `axis` after dragging its `side` face handle by (dx, dy)
  // image pixels from where the drag started (box = the clip box then, cam = the camera
  // of the frame shown). The motion's component along the face normal's image direction
  // moves the face, motion across it does nothing: the pointer is projected onto the
  // image of the axis through the face centre (a straight line, perspective or not), and
  // the face goes where the ray through that point meets the axis, so the handle stays
  // under the pointer. The face stops at the opposite face and at the volume's box, so
  // 0 <= lo <= hi <= 1 holds, as clipPair keeps it.
  function faceDrag(cam, bounds, box, axis, side, dx, dy, width, height) {
    const lo = box[0][axis], hi = box[1][axis], f0 = side === "lo" ? lo : hi;
    const s = faceAxisPx(cam, bounds, box, axis, side, width, height);
    const n2 = s ? s[0] * s[0] + s[1] * s[1] : 0;
    if (!(n2 >= MIN_AXIS_PX * MIN_AXIS_PX)) return [lo, hi];
    const [wlo, whi] = clipBoxWorld(bounds, box);
    const c = faceHandles(wlo, whi)[2 * axis + (side === "hi" ? 1 : 0)].point;
    const p0 = projectPoint(cam, c, width, height);
    const k = (dx * s[0] + dy * s[1]) / n2;
    const [o, d] = pixelRay(cam, p0[0] + k * s[0], p0[1] + k * s[1], width, height);
    // Closest point of the axis line c + t a (t in box fractions) to the ray o + r d.
    const a = [0, 0, 0]; a[axis] = bounds[1][axis] - bounds[0][axis];
    const w0 = sub(c, o), A = dot(a, a), B = dot(a, d), C = dot(d, d), D = dot(a, w0), E = dot(d, w0);
    const den = A * C - B * B;
    // A ray along the axis (the face head-on) was refused above; this guards rounding.
    let t = den > 1e-12 * A * C ? (B * E - C * D) / den : k;
    if (cam.perspective && depth(cam, c.map((v, j) => v + t * a[j])) <= 0) t = k;  // beyond the horizon
    const f = f0 + t;
    return side === "lo" ? [Math.max(0, Math.min(hi, f)), hi] : [lo, Math.min(1, Math.max(lo, f))];
  }

  // --- clip planes -------------------------------------------------------------------------
  // A plane is the render message's [px, py, pz, nx, ny, nz]: a point in fractions of the
  // volume box and a normal in world axes (any length); the renderer keeps the side the
  // normal points to (session.clip_world). The maps below work in world units with the
  // unit normal n: the plane is {x : n . (x - p) = 0} with p the point in world units, and
  // its offset is n . (p - c), c the volume box's centre, so offsets from -h to h (h the
  // box's half extent along n, planeHalfRange) sweep the plane through the whole box.
  const add3 = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
  const scale3 = (a, k) => [a[0] * k, a[1] * k, a[2] * k];
  const cross3 = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm3 = (a) => Math.hypot(a[0], a[1], a[2]);
  const unit3 = (a) => { const n = norm3(a); return n > 0 ? scale3(a, 1 / n) : null; };
  const boxCentre = (bounds) => [0, 1, 2].map((j) => 0.5 * (bounds[0][j] + bounds[1][j]));
  const boxDiagonal = (bounds) => norm3(sub(bounds[1], bounds[0]));
  const clamp01 = (t) => Math.max(0, Math.min(1, t));

  // World point of box fractions f, and the fractions of world point p.
  function fracToWorld(bounds, f) { return f.map((t, j) => bounds[0][j] + t * (bounds[1][j] - bounds[0][j])); }
  function worldToFrac(bounds, p) { return p.map((v, j) => (v - bounds[0][j]) / (bounds[1][j] - bounds[0][j])); }

  // Half extent h of the volume box along `normal` (its support function): the plane
  // with that normal meets the box for offsets in [-h, h].
  function planeHalfRange(bounds, normal) {
    const n = unit3(normal);
    return 0.5 * [0, 1, 2].reduce((s, j) => s + Math.abs(n[j]) * (bounds[1][j] - bounds[0][j]), 0);
  }

  // Offset (world units) of `plane` along its unit normal from the volume box's centre.
  function planeOffset(bounds, plane) {
    return dot(unit3(plane.slice(3)), sub(fracToWorld(bounds, plane.slice(0, 3)), boxCentre(bounds)));
  }

  // The point (fractions) of the plane with unit normal n at offset s (|s| <= h) on the
  // box's diagonal that runs from the corner least along n through the centre to the
  // corner farthest along n (an axis with no normal component stays at its middle, so an
  // axis-aligned plane's point is the centre of its cut): inside the box for every s,
  // continuous in s, f_j = 1/2 + (s / 2h) sign(n_j).
  function centredPoint(bounds, n, s) {
    const h = planeHalfRange(bounds, n);
    const r = h > 0 ? Math.max(-1, Math.min(1, s / h)) : 0;
    return n.map((v) => clamp01(0.5 + 0.5 * r * (Math.abs(v) > 1e-9 ? Math.sign(v) : 0)));
  }

  const inBox = (f) => f.every((t) => t >= 0 && t <= 1);

  // `plane` moved along its normal to offset s (clamped to [-h, h]), its normal made unit:
  // the point slides along the normal when that keeps it inside the box (a typed offset
  // moves the centre handle straight along the normal), else it goes to centredPoint.
  function planeAtOffset(bounds, plane, s) {
    const n = unit3(plane.slice(3)), h = planeHalfRange(bounds, n);
    const t = Math.max(-h, Math.min(h, s));
    const p = add3(fracToWorld(bounds, plane.slice(0, 3)), scale3(n, t - planeOffset(bounds, plane)));
    const f = worldToFrac(bounds, p);
    return [...(inBox(f) ? f : centredPoint(bounds, n, t)), ...n];
  }

  // `plane` with its point moved within the plane to centredPoint when it lies on the box's
  // surface (a drag stopped there): the next drag along the normal can go on from there.
  function planeRecentre(bounds, plane) {
    const f = plane.slice(0, 3);
    if (f.every((t) => t > 1e-9 && t < 1 - 1e-9)) return plane.slice();
    const n = unit3(plane.slice(3));
    return [...centredPoint(bounds, n, planeOffset(bounds, plane)), ...plane.slice(3)];
  }

  // The plane "add plane" creates: through the centre of the clip box `box` (fractions),
  // its normal the world axis closest to the view direction there (towards the box from
  // the eye), signed so the renderer keeps the far side: the new plane cuts away the half
  // of the clip box facing the camera and shows its inside. An axis, not the view
  // direction itself, because a plane seen exactly head-on has no draggable centre handle
  // (planeAxisPx) and its offset would be a depth, while an axis-aligned plane is a slice
  // of the volume whose offset reads as a position along that axis. cam null: +x.
  function newPlane(cam, bounds, box) {
    const f = [0, 1, 2].map((j) => 0.5 * (box[0][j] + box[1][j]));
    const n = [0, 0, 0];
    if (!cam) { n[0] = 1; return [...f, ...n]; }
    const d = cam.perspective ? sub(fracToWorld(bounds, f), cam.eye) : cam.forward;
    let j = 0;
    for (let i = 1; i < 3; i++) if (Math.abs(d[i]) > Math.abs(d[j])) j = i;
    n[j] = d[j] < 0 ? -1 : 1;
    return [...f, ...n];
  }

  // The polygon where the plane through world point `point` with normal `normal` cuts the
  // world box [lo, hi]: its vertices (world points), convex, in counter-clockwise order
  // seen from the side the normal points to; [] when the plane misses the box. Vertices are
  // the box corners on the plane and the crossings of the edges whose ends lie strictly on
  // opposite sides (a tolerance of 1e-12 of the diagonal decides "on"), so a plane through
  // a face gives that face, whichever way its normal points.
  function planeBoxPolygon(lo, hi, point, normal) {
    const n = unit3(normal);
    const eps = 1e-12 * norm3(sub(hi, lo));
    const pts = [];
    const push = (q) => { if (!pts.some((r) => norm3(sub(q, r)) <= 1e3 * eps)) pts.push(q); };
    for (const [a, b] of boxEdges(lo, hi)) {
      const da = dot(n, sub(a, point)), db = dot(n, sub(b, point));
      const sa = da > eps ? 1 : da < -eps ? -1 : 0, sb = db > eps ? 1 : db < -eps ? -1 : 0;
      if (sa === 0) push(a);
      if (sb === 0) push(b);
      if (sa * sb < 0) push(lerp3(a, b, da / (da - db)));
    }
    if (pts.length < 3) return pts.length ? pts : [];
    const m = scale3(pts.reduce(add3, [0, 0, 0]), 1 / pts.length);
    // u, v, n right-handed: increasing angle from u towards v is counter-clockwise seen from +n.
    const k = Math.abs(n[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0];
    const u = unit3(cross3(k, n)), v = cross3(n, u);
    const ang = (q) => Math.atan2(dot(sub(q, m), v), dot(sub(q, m), u));
    return pts.map((q) => [ang(q), q]).sort((x, y) => x[0] - y[0]).map((e) => e[1]);
  }

  // Length of the normal handle's stick, as a fraction of the volume box's diagonal.
  const PLANE_TIP_FRACTION = 0.2;

  // A plane's two handles in world units: `centre` (its point), `tip` (centre + L n, the
  // end of the normal's stick, L = PLANE_TIP_FRACTION of the box diagonal), `normal` (unit)
  // and `length` L.
  function planeHandles(bounds, plane) {
    const centre = fracToWorld(bounds, plane.slice(0, 3)), normal = unit3(plane.slice(3));
    const length = PLANE_TIP_FRACTION * boxDiagonal(bounds);
    return { centre, tip: add3(centre, scale3(normal, length)), normal, length };
  }

  // Image pixels [px, py] the centre handle moves when the plane sweeps the whole box along
  // its normal (2h world units), the derivative at the handle like faceAxisPx; null when
  // the handle is behind the eye. Shorter than MIN_AXIS_PX: the normal is seen nearly
  // head-on and the centre handle is not draggable.
  function planeAxisPx(cam, bounds, plane, width, height) {
    const { centre, normal } = planeHandles(bounds, plane);
    const step = 1e-3, span = 2 * planeHalfRange(bounds, normal);
    const p0 = projectPoint(cam, centre, width, height);
    const p1 = projectPoint(cam, add3(centre, scale3(normal, step * span)), width, height);
    if (!p0 || !p1) return null;
    return [(p1[0] - p0[0]) / step, (p1[1] - p0[1]) / step];
  }

  // `plane` after dragging its centre handle by (dx, dy) image pixels from where the drag
  // started (plane and cam as they were then): faceDrag's rule along the normal. The motion's
  // component along the normal's image direction moves the plane, the handle staying under
  // the pointer (the point goes where the ray through the projected pointer meets the
  // normal's line through the centre); motion across it does nothing. The point stops where
  // that line leaves the volume box (the server refuses points outside it). A normal seen
  // nearly head-on (planeAxisPx under MIN_AXIS_PX) does not move the plane.
  function planeDrag(cam, bounds, plane, dx, dy, width, height) {
    const s = planeAxisPx(cam, bounds, plane, width, height);
    const n2 = s ? s[0] * s[0] + s[1] * s[1] : 0;
    if (!(n2 >= MIN_AXIS_PX * MIN_AXIS_PX)) return plane.slice();
    const { centre: c, normal } = planeHandles(bounds, plane);
    const a = scale3(normal, 2 * planeHalfRange(bounds, normal));  // t = 1: one whole sweep
    const p0 = projectPoint(cam, c, width, height);
    const k = (dx * s[0] + dy * s[1]) / n2;
    const [o, d] = pixelRay(cam, p0[0] + k * s[0], p0[1] + k * s[1], width, height);
    const w0 = sub(c, o), A = dot(a, a), B = dot(a, d), C = dot(d, d), D = dot(a, w0), E = dot(d, w0);
    const den = A * C - B * B;
    let t = den > 1e-12 * A * C ? (B * E - C * D) / den : k;
    if (cam.perspective && depth(cam, add3(c, scale3(a, t))) <= 0) t = k;  // beyond the horizon
    // The interval of t that keeps c + t a inside the box [lo, hi].
    let tlo = -Infinity, thi = Infinity;
    for (let j = 0; j < 3; j++) {
      if (Math.abs(a[j]) < 1e-15 * norm3(a)) continue;
      const t1 = (bounds[0][j] - c[j]) / a[j], t2 = (bounds[1][j] - c[j]) / a[j];
      tlo = Math.max(tlo, Math.min(t1, t2)); thi = Math.min(thi, Math.max(t1, t2));
    }
    t = Math.max(Math.min(tlo, 0), Math.min(Math.max(thi, 0), t));
    const f = worldToFrac(bounds, add3(c, scale3(a, t))).map(clamp01);
    return [...f, ...plane.slice(3)];
  }

  // `plane` after dragging its normal's tip handle by (dx, dy) image pixels from where the
  // drag started: the tip follows the pointer on the sphere of radius L (planeHandles)
  // about the centre, which stays put, and the normal is the unit vector from the centre to
  // the tip. The ray through the pointer meets the sphere twice; the tip stays on the half
  // it started on: the near one when the tip faced the eye at the start ((tip - centre) .
  // ray < 0), the far one otherwise. A ray that misses the sphere puts the tip on the
  // sphere's outline (the point of the sphere closest to the ray), where the two halves
  // meet, so the normal turns continuously to lie across the view; to go on to the other
  // half, start a new drag there or flip the plane. The tip is exactly under the pointer
  // whenever the ray meets the sphere.
  function planeTilt(cam, bounds, plane, dx, dy, width, height) {
    const { centre: c, tip, length: L } = planeHandles(bounds, plane);
    const q0 = projectPoint(cam, tip, width, height);
    if (!q0) return plane.slice();
    const d0 = pixelRay(cam, q0[0], q0[1], width, height)[1];
    const near = dot(sub(tip, c), d0) < 0;
    const [o, d] = pixelRay(cam, q0[0] + dx, q0[1] + dy, width, height);
    const oc = sub(o, c), A = dot(d, d), B = dot(d, oc), C = dot(oc, oc) - L * L;
    const disc = B * B - A * C;
    const r = disc > 0 ? (-B + (near ? -1 : 1) * Math.sqrt(disc)) / A : -B / A;
    const n = unit3(sub(add3(o, scale3(d, r)), c));
    return n ? [...plane.slice(0, 3), ...n] : plane.slice();
  }

  // The render message's `clip` for the page's clip state: box and cap as they are, and
  // the planes of the enabled rows only (rows are {plane, enabled}), at most `max`.
  function clipMessage(box, rows, cap, max) {
    const planes = rows.filter((r) => r.enabled).map((r) => r.plane.slice()).slice(0, max);
    return { box: box.map((c) => c.slice()), planes, cap: Boolean(cap) };
  }

  // Keyboard: degrees an arrow key orbits (shift: fine steps), the zoom factor of + / -,
  // and the fraction of a plane's half range that [ / ] move it along its normal.
  const KEY_ORBIT_DEG = 5, KEY_ORBIT_FINE_DEG = 1, KEY_ZOOM = 1.1, KEY_PLANE_FRACTION = 0.05;

  // What a key does over the view: {camera: {azimuth, elevation, zoom}} for the orbit and
  // zoom keys (arrows as a drag of the same sense, so the surface moves with the arrow),
  // {plane: steps} to move the current plane along its normal ([ back, ] forward), {flip:
  // true} to keep its other side (f), or null for any other key.
  function keyAction(key, shift, camera) {
    const step = (shift ? KEY_ORBIT_FINE_DEG : KEY_ORBIT_DEG) / ORBIT_DEG_PER_PX;
    const orbit = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] }[key];
    if (orbit) {
      const ang = orbitDrag(camera.azimuth, camera.elevation, orbit[0], orbit[1]);
      return { camera: { azimuth: ang.azimuth, elevation: ang.elevation, zoom: camera.zoom } };
    }
    const zoom = { "+": KEY_ZOOM, "=": KEY_ZOOM, "-": 1 / KEY_ZOOM, _: 1 / KEY_ZOOM }[key];
    if (zoom) {
      return { camera: { azimuth: camera.azimuth, elevation: camera.elevation,
                         zoom: Math.max(0.05, Math.min(50, camera.zoom * zoom)) } };
    }
    if (key === "[" || key === "]") return { plane: (key === "]" ? 1 : -1) * (shift ? 0.25 : 1) };
    if (key === "f" || key === "F") return { flip: true };
    return null;
  }

  // `plane` moved `steps` key steps (KEY_PLANE_FRACTION of its half range each) along
  // its normal, held inside the box as the offset slider holds it.
  function planeNudge(bounds, plane, steps) {
    const h = planeHalfRange(bounds, plane.slice(3));
    return planeAtOffset(bounds, plane, planeOffset(bounds, plane) + steps * KEY_PLANE_FRACTION * h);
  }

  const api = { orbitDrag, keyAction, planeNudge, KEY_ORBIT_DEG, KEY_ZOOM, KEY_PLANE_FRACTION, opacityAt, sliderValue, sliderPos, clipPair, ORBIT_DEG_PER_PX, SNAP_PX, SLIDER_STEPS,
                depth, projectPoint, clipSegment, clipBoxWorld, boxEdges, faceHandles, pickHandle, faceAxisPx,
                pixelRay, faceDrag, MIN_AXIS_PX,
                fracToWorld, worldToFrac, planeHalfRange, planeOffset, planeAtOffset, planeRecentre, newPlane,
                planeBoxPolygon, planeHandles, planeAxisPx, planeDrag, planeTilt, clipMessage, PLANE_TIP_FRACTION };
  if (typeof module !== "undefined" && module.exports) module.exports = api;
  else root.sparsecastInteraction = api;
})(typeof window !== "undefined" ? window : globalThis);
