"""The viewer's pointer mappings (static/interaction.js), run under node.

Skips when node is not installed: the page itself needs only a browser.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from importlib import resources

import pytest

NODE = shutil.which("node")
pytestmark = pytest.mark.skipif(NODE is None, reason="node not installed (needed to run the viewer's JS)")
SCRIPT = resources.files("sparsecast.viewer") / "static" / "interaction.js"


def js(expr: str):
    """Value of ``expr`` (JSON-serialisable) with interaction.js loaded as ``ui``."""
    prog = f"const ui = require({json.dumps(str(SCRIPT))}); console.log(JSON.stringify({expr}));"
    out = subprocess.run([NODE, "-e", prog], capture_output=True, text=True, timeout=30, check=True)
    return json.loads(out.stdout)


def test_opacity_snaps_to_zero_near_the_floor():
    h, pad = 120, 6
    floor = h - pad
    assert js(f"[{floor}, {floor - 1}, {floor - 4}, {h}].map((y) => ui.opacityAt(y, {h}, {pad}))") == [0, 0, 0, 0]
    a = js(f"ui.opacityAt({floor - 5}, {h}, {pad})")
    assert 0 < a < 0.1
    assert js(f"ui.opacityAt({h // 2}, {h}, {pad})") == pytest.approx(0.5)
    assert js(f"[ui.opacityAt({pad}, {h}, {pad}), ui.opacityAt(0, {h}, {pad})]") == [1, 1]


def _front_point_on_screen(az: float, el: float) -> tuple[float, float]:
    """Screen position (right, up) of the surface point that faces the camera at (0, 0)."""
    import numpy as np

    import sparsecast as sc

    vol = sc.Volume(np.zeros((9, 9, 9), np.float32))
    front = vol.center + (sc.Camera.orbit(vol, 0, 0).eye - vol.center) * 0.1
    cam = sc.Camera.orbit(vol, az, el)
    forward, right, up = cam.basis()
    d = front - cam.eye
    return float(d @ right / (d @ forward)), float(d @ up / (d @ forward))


@pytest.mark.parametrize("dx, dy", [(10, 0), (-10, 0), (0, 10), (0, -10), (7, -5)])
def test_orbit_drag_moves_the_surface_with_the_mouse(dx, dy):
    """Dragging right moves the surface under the cursor right; dragging down (client y
    grows) moves it down, i.e. against the camera's up vector."""
    ang = js(f"ui.orbitDrag(0, 0, {dx}, {dy})")
    x0, y0 = _front_point_on_screen(0.0, 0.0)
    x1, y1 = _front_point_on_screen(ang["azimuth"], ang["elevation"])
    assert (x1 - x0) * dx >= 0 and (dx == 0 or abs(x1 - x0) > 1e-3)
    assert (y1 - y0) * -dy >= 0 and (dy == 0 or abs(y1 - y0) > 1e-3)
    assert 0 <= ang["azimuth"] < 360 and -90 < ang["elevation"] < 90


def test_sliders_map_onto_the_range_and_back():
    n = js("ui.SLIDER_STEPS")
    assert js(f"[0, {n // 2}, {n}, -5, {n + 9}].map((p) => ui.sliderValue(p, -2, 6))") == [-2, 2, 6, -2, 6]
    assert js(f"[-2, 2, 6, -100, 100].map((v) => ui.sliderPos(v, -2, 6))") == [0, n // 2, n, 0, n]
    assert js("ui.sliderPos(3, 1, 1)") == 0  # a constant volume: no range to slide over
    v = js(f"ui.sliderValue(ui.sliderPos(0.3141, 0, 1), 0, 1)")
    assert abs(v - 0.3141) <= 0.5 / n


def test_clip_sliders_keep_lo_below_hi():
    assert js("ui.clipPair(0.2, 0.7, 'lo')") == [0.2, 0.7]
    assert js("ui.clipPair(0.8, 0.7, 'lo')") == [0.8, 0.8]  # lo pushed hi up
    assert js("ui.clipPair(0.3, 0.1, 'hi')") == [0.1, 0.1]  # hi pushed lo down
