// sparsecast viewer: pure mappings from pointer motion and sliders to camera, TF, clip and isovalues.
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

  const api = { orbitDrag, opacityAt, sliderValue, sliderPos, clipPair, ORBIT_DEG_PER_PX, SNAP_PX, SLIDER_STEPS };
  if (typeof module !== "undefined" && module.exports) module.exports = api;
  else root.sparsecastInteraction = api;
})(typeof window !== "undefined" ? window : globalThis);
