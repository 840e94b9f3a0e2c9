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
