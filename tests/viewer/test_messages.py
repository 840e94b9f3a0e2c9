"""Validation of viewer client messages: good ones parse, hostile ones are rejected."""

from __future__ import annotations

import json

import pytest

from sparsecast.errors import ParameterError
from sparsecast.transfer import PRESETS
from sparsecast.viewer.messages import (
    MAX_MESSAGE_BYTES,
    MAX_SIDE,
    MAX_TF_POINTS,
    PREVIEW_SIDE,
    CameraSpec,
    IndexSpec,
    MessageError,
    frame_size,
    parse_message,
)

INDICES = ["naive", "grid-mm", "grid-pc"]


def parse(obj) -> object:
    raw = obj if isinstance(obj, (str, bytes)) else json.dumps(obj)
    return parse_message(raw, indices=INDICES, presets=PRESETS)


GOOD_TF = {"points": [[0, 0, 0, 0, 0], [0.2, 0.1, 0.2, 0.3, 0.0], [1, 1, 1, 1, 0.8]],
           "colormap": "viridis", "value_range": [0.0, 1.0]}


def test_full_message_parses():
    req = parse({"type": "render", "seq": 7, "camera": {"azimuth": 390, "elevation": -20, "zoom": 2},
                 "tf": GOOD_TF, "index": {"name": "grid-pc", "cell": 8},
                 "width": 640, "height": 480, "preview": True, "format": "png"})
    assert req.seq == 7
    assert req.camera == CameraSpec(30.0, -20.0, 2.0)  # azimuth wrapped
    assert req.tf.colormap == "viridis" and len(req.tf.points) == 3 and req.tf.value_range == (0.0, 1.0)
    assert req.index == IndexSpec("grid-pc", 8)
    assert (req.width, req.height, req.preview, req.format) == (640, 480, True, "png")
    hash(req.tf)  # usable as a cache key


def test_minimal_message_and_defaults():
    req = parse({"type": "render"})
    assert req.camera is None and req.tf is None and req.index is None
    assert req.preview is False and req.format == "jpeg"


def test_points_are_sorted_and_colormap_may_be_null():
    tf = dict(GOOD_TF, points=[[0.9, 1, 1, 1, 1], [0.1, 0, 0, 0, 0]], colormap=None)
    req = parse({"type": "render", "tf": tf})
    assert [p[0] for p in req.tf.points] == [0.1, 0.9]
    assert req.tf.colormap is None


def test_integral_floats_accepted_for_sizes():
    req = parse({"type": "render", "width": 256.0, "height": 128})
    assert (req.width, req.height) == (256, 128)


def test_frame_size_limits():
    assert frame_size(None, None, False) == (512, 512)
    assert frame_size(1024, 1024, True) == (PREVIEW_SIDE, PREVIEW_SIDE)
    assert frame_size(1024, 512, True) == (256, 128)
    assert frame_size(200, 100, True) == (200, 100)  # already small: kept
    assert frame_size(MAX_SIDE, MAX_SIDE, False) == (MAX_SIDE, MAX_SIDE)


BAD = [
    # (message, words the error must contain)
    ("not json", "JSON"),
    ("{\"type\": \"render\",", "JSON"),
    ('{"type": "render", "seq": NaN}', "NaN"),
    ('{"type": "render", "camera": {"azimuth": Infinity, "elevation": 0, "zoom": 1}}', "Infinity"),
    ("[1, 2, 3]", "object"),
    ("null", "object"),
    ('"render"', "object"),
    ({"type": "camera"}, "type"),
    ({}, "type"),
    ({"type": "render", "extra": 1}, "unknown key"),
    ({"type": "render", "__proto__": {}}, "unknown key"),
    ({"type": "render", "file": "/etc/passwd"}, "unknown key"),
    ({"type": "render", "camera": {"azimuth": "30", "elevation": 0, "zoom": 1}}, "camera.azimuth"),
    ({"type": "render", "camera": {"azimuth": True, "elevation": 0, "zoom": 1}}, "camera.azimuth"),
    ({"type": "render", "camera": {"azimuth": 0, "elevation": 95, "zoom": 1}}, "camera.elevation"),
    ({"type": "render", "camera": {"azimuth": 0, "elevation": 0, "zoom": 0}}, "camera.zoom"),
    ({"type": "render", "camera": {"azimuth": 0, "elevation": 0, "zoom": 1e308 * 10}}, "Infinity"),
    ('{"type": "render", "camera": {"azimuth": 0, "elevation": 0, "zoom": 1e400}}', "camera.zoom"),
    ({"type": "render", "camera": {"azimuth": 0, "elevation": 0}}, "camera.zoom"),
    ({"type": "render", "camera": {"azimuth": 0, "elevation": 0, "zoom": 1, "fov": 3}}, "unknown key"),
    ({"type": "render", "camera": [0, 0, 1]}, "camera"),
    ({"type": "render", "camera": {"azimuth": 10 ** 400, "elevation": 0, "zoom": 1}}, "camera.azimuth"),
    ({"type": "render", "width": 100000, "height": 100}, "width"),
    ({"type": "render", "width": 2 ** 40, "height": 2 ** 40}, "width"),
    ({"type": "render", "width": 0, "height": 100}, "width"),
    ({"type": "render", "width": -5, "height": 100}, "width"),
    ({"type": "render", "height": 12.5}, "height"),
    ({"type": "render", "width": "512"}, "width"),
    ({"type": "render", "preview": "yes"}, "preview"),
    ({"type": "render", "preview": 1}, "preview"),
    ({"type": "render", "format": "bmp"}, "format"),
    ({"type": "render", "format": "../../x.png"}, "format"),
    ({"type": "render", "seq": -1}, "seq"),
    ({"type": "render", "seq": "1"}, "seq"),
    ({"type": "render", "tf": dict(GOOD_TF, points=[[0, 0, 0, 0, 0]] * (MAX_TF_POINTS + 1))}, "tf.points"),
    ({"type": "render", "tf": dict(GOOD_TF, points=[])}, "tf.points"),
    ({"type": "render", "tf": dict(GOOD_TF, points=[[0, 0, 0, 0]])}, "tf.points[0]"),
    ({"type": "render", "tf": dict(GOOD_TF, points=[[0, 0, 0, 0, 1.5]])}, "tf.points[0][4]"),
    ({"type": "render", "tf": dict(GOOD_TF, points=[[-0.1, 0, 0, 0, 0]])}, "tf.points[0][0]"),
    ({"type": "render", "tf": dict(GOOD_TF, points=[[0, 0, 0, 0, None]])}, "tf.points[0][4]"),
    ({"type": "render", "tf": dict(GOOD_TF, points="0,0,0,0,0")}, "tf.points"),
    ({"type": "render", "tf": dict(GOOD_TF, colormap="/etc/passwd")}, "tf.colormap"),
    ({"type": "render", "tf": dict(GOOD_TF, colormap="../../../pyproject.toml")}, "tf.colormap"),
    ({"type": "render", "tf": dict(GOOD_TF, colormap=7)}, "tf.colormap"),
    ({"type": "render", "tf": dict(GOOD_TF, value_range=[1, 1])}, "tf.value_range"),
    ({"type": "render", "tf": dict(GOOD_TF, value_range=[2, 1])}, "tf.value_range"),
    ({"type": "render", "tf": dict(GOOD_TF, value_range=[0, 1e301])}, "tf.value_range"),
    ({"type": "render", "tf": dict(GOOD_TF, value_range=[0])}, "tf.value_range"),
    ({"type": "render", "tf": {k: v for k, v in GOOD_TF.items() if k != "colormap"}}, "tf.colormap"),
    ({"type": "render", "tf": dict(GOOD_TF, path="tf.json")}, "unknown key"),
    ({"type": "render", "index": {"name": "../../etc/passwd"}}, "index.name"),
    ({"type": "render", "index": {"name": "x" * 10000}}, "index.name"),
    ({"type": "render", "index": {"name": "grid-pc", "cell": 7}}, "index.cell"),
    ({"type": "render", "index": {"name": "grid-pc", "cell": 4096}}, "index.cell"),
    ({"type": "render", "index": {"name": "grid-pc", "cell": "8"}}, "index.cell"),
    ({"type": "render", "index": {"cell": 8}}, "index.name"),
    ({"type": "render", "index": "grid-pc"}, "index"),
]


@pytest.mark.parametrize("msg, words", BAD, ids=[f"bad{i}" for i in range(len(BAD))])
def test_bad_messages_rejected_with_named_field(msg, words):
    with pytest.raises(MessageError) as info:
        parse(msg)
    assert words in str(info.value)
    assert isinstance(info.value, ParameterError)  # one exception family
    assert len(str(info.value)) < 400  # hostile input is not echoed at length


def test_huge_and_binary_and_deep_messages_rejected():
    with pytest.raises(MessageError, match="larger"):
        parse(json.dumps({"type": "render", "pad": "x" * MAX_MESSAGE_BYTES}))
    with pytest.raises(MessageError, match="binary"):
        parse(b'{"type": "render"}')
    with pytest.raises(MessageError):
        parse_message(None, indices=INDICES, presets=PRESETS)
    with pytest.raises(MessageError):
        parse("[" * 30000 + "]" * 30000)  # too large, and deeply nested
    with pytest.raises(MessageError):
        parse("[" * 5000 + "]" * 5000)  # deeply nested but small


def test_import_sparsecast_does_not_load_the_web_stack():
    import subprocess
    import sys

    code = ("import sys, sparsecast, sparsecast.viewer, sparsecast.viewer.messages; "
            "print(sorted(m for m in ('starlette', 'uvicorn', 'websockets') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]"


def test_camera_pan_parses_and_is_checked():
    cam = {"azimuth": 0, "elevation": 0, "zoom": 1, "pan": [0.5, -1.25]}
    assert parse({"type": "render", "camera": cam}).camera.pan == (0.5, -1.25)
    no_pan = {k: v for k, v in cam.items() if k != "pan"}
    assert parse({"type": "render", "camera": no_pan}).camera.pan == (0.0, 0.0)
    with pytest.raises(MessageError):  # NaN is refused before any field is read
        parse(json.dumps({"type": "render", "camera": dict(cam, pan=[float("nan"), 0])}))
    for bad in ([1.0], [0, 1, 2], "left", [100, 0], [True, 0], {"x": 1}):
        with pytest.raises(MessageError, match="pan"):
            parse(json.dumps({"type": "render", "camera": dict(cam, pan=bad)}))
