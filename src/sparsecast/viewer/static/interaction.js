// sparsecast viewer: pure mappings from pointer motion to TF values.
// No DOM here, so tests can run it under node (tests/viewer/test_interaction.py).
"use strict";
(function (root) {
  // An opacity point dragged within this many pixels of the editor's floor is set to
  // exactly 0: a TF that is 0 (not 0.004) below a value is what lets the renderer
  // classify that range as empty space and skip it.
  const SNAP_PX = 4;

  // Opacity in [0, 1] for pointer height y (canvas px) in an editor of `height` px
  // with `pad` px of padding; near the floor it snaps to exactly 0.
  function opacityAt(y, height, pad) {
    const span = height - 2 * pad, up = height - pad - y;
    if (up <= SNAP_PX) return 0;
    return Math.max(0, Math.min(1, up / span));
  }

  const api = { opacityAt, SNAP_PX };
  if (typeof module !== "undefined" && module.exports) module.exports = api;
  else root.sparsecastInteraction = api;
})(typeof window !== "undefined" ? window : globalThis);
