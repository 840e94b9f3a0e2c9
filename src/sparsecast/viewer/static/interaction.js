// sparsecast viewer: pure mappings from pointer motion and sliders to camera, TF, clip and isovalues,
// and the projection of the clip box onto the image (its drag handles).
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

  const api = { orbitDrag, opacityAt, sliderValue, sliderPos, clipPair, ORBIT_DEG_PER_PX, SNAP_PX, SLIDER_STEPS,
                depth, projectPoint, clipSegment, clipBoxWorld, boxEdges, faceHandles, pickHandle, faceAxisPx,
                pixelRay, faceDrag, MIN_AXIS_PX };
  if (typeof module !== "undefined" && module.exports) module.exports = api;
  else root.sparsecastInteraction = api;
})(typeof window !== "undefined" ? window : globalThis);
