"""Validation of viewer client messages: good ones parse, hostile ones are rejected."""

from __future__ import annotations

import json

import pytest

from sparsecast.errors import ParameterError
from sparsecast.transfer import PRESETS
from sparsecast.viewer.messages import (
    MAX_CLIP_PLANES,
    MAX_ISOVALUES,
    MAX_MESSAGE_BYTES,
    MAX_SIDE,
    MAX_TF_POINTS,
    PREVIEW_SIDE,
    CameraSpec,
    ClipSpec,
    IndexSpec,
    LabelSpec,
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
    ({"type": "render", "clip": {"box": [[0, 0, 0], [1, 1, 1]], "cap": "yes"}}, "clip.cap"),
    ({"type": "render", "clip": {"cap": 1}}, "clip.cap"),
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


# -- mode / iso / clip / labels / time -------------------------------------------------
LABEL_IDS = (0, 1, 2, 7)


def parse_ctx(obj, labels=None, steps=0):
    return parse_message(json.dumps(obj), indices=INDICES, presets=PRESETS, label_ids=labels, steps=steps)


def test_mode_iso_clip_labels_time_parse():
    req = parse_ctx({"type": "render", "mode": "iso+dvr", "iso": [0.25, -3],
                     "clip": {"box": [[0, 0.1, 0.2], [1, 0.5, 0.2]], "planes": [[0.5, 0.5, 0.5, 1, 0, -2]]},
                     "time": 4}, steps=5)
    assert req.mode == "iso+dvr" and req.iso == (0.25, -3.0) and req.time == 4
    assert req.clip == ClipSpec(((0.0, 0.1, 0.2), (1.0, 0.5, 0.2)), ((0.5, 0.5, 0.5, 1.0, 0.0, -2.0),))
    assert not req.clip.is_full and parse({"type": "render", "clip": {}}).clip.is_full
    assert parse({"type": "render", "iso": 12.5}).iso == (12.5,)  # a number is one isovalue
    req = parse_ctx({"type": "render", "labels": {"visible": [7, 1, 1], "colors": [[2, 1, 0, 0, 0.5]]}},
                    labels=LABEL_IDS)
    assert req.labels == LabelSpec((1, 7), ((2, 1.0, 0.0, 0.0, 0.5),))
    assert parse_ctx({"type": "render", "labels": {"visible": []}}, labels=LABEL_IDS).labels.visible == ()
    assert parse_ctx({"type": "render", "labels": {}}, labels=LABEL_IDS).labels == LabelSpec(None, ())
    req = parse({"type": "render"})
    assert (req.mode, req.iso, req.clip, req.labels, req.time) == (None, None, None, None, None)


BAD_NEW = [
    # (message, label ids or None, steps, words the error must contain)
    ({"mode": "mip"}, None, 0, "mode"),
    ({"mode": 1}, None, 0, "mode"),
    ({"mode": "iso"}, LABEL_IDS, 0, "label volume"),
    ({"iso": []}, None, 0, "iso"),
    ({"iso": list(range(MAX_ISOVALUES + 1))}, None, 0, "iso"),
    ({"iso": "0.5"}, None, 0, "iso[0]"),
    ({"iso": [0.5, None]}, None, 0, "iso[1]"),
    ({"iso": [1e301]}, None, 0, "iso[0]"),
    ('{"type": "render", "iso": [NaN]}', None, 0, "NaN"),
    ({"iso": True}, None, 0, "iso[0]"),
    ({"clip": [0, 1]}, None, 0, "clip"),
    ({"clip": {"box": [[0, 0, 0], [1, 1]]}}, None, 0, "clip.box"),
    ({"clip": {"box": [[0, 0, 0], [1, 1, 1.5]]}}, None, 0, "clip.box[1][2]"),
    ({"clip": {"box": [[0, -0.1, 0], [1, 1, 1]]}}, None, 0, "clip.box[0][1]"),
    ({"clip": {"box": [[0.6, 0, 0], [0.4, 1, 1]]}}, None, 0, "x0 <= x1"),
    ({"clip": {"box": [[0, 0, "0"], [1, 1, 1]]}}, None, 0, "clip.box[0][2]"),
    ({"clip": {"planes": [[0.5, 0.5, 0.5, 0, 0, 0]]}}, None, 0, "non-zero normal"),
    ({"clip": {"planes": [[0.5, 0.5, 0.5, 1, 0]]}}, None, 0, "clip.planes[0]"),
    ({"clip": {"planes": [[2, 0.5, 0.5, 1, 0, 0]]}}, None, 0, "clip.planes[0][0]"),
    ({"clip": {"planes": [[0.5, 0.5, 0.5, 1, 0, 0]] * (MAX_CLIP_PLANES + 1)}}, None, 0, "clip.planes"),
    ({"clip": {"planes": "x"}}, None, 0, "clip.planes"),
    ({"clip": {"sphere": 1}}, None, 0, "unknown key"),
    ({"labels": {"visible": [1]}}, None, 0, "not show a label volume"),
    ({"labels": {"visible": [3]}}, LABEL_IDS, 0, "id 3 does not occur"),
    ({"labels": {"visible": ["1"]}}, LABEL_IDS, 0, "labels.visible[0]"),
    ({"labels": {"visible": 1}}, LABEL_IDS, 0, "labels.visible"),
    ({"labels": {"visible": [1.5]}}, LABEL_IDS, 0, "labels.visible[0]"),
    ({"labels": {"visible": [0] * 5}}, LABEL_IDS, 0, "labels.visible"),
    ({"labels": {"colors": [[1, 1, 0, 0]]}}, LABEL_IDS, 0, "labels.colors[0]"),
    ({"labels": {"colors": [[1, 1, 0, 0, 2]]}}, LABEL_IDS, 0, "labels.colors[0][4]"),
    ({"labels": {"colors": [[9, 1, 0, 0, 1]]}}, LABEL_IDS, 0, "id 9"),
    ({"labels": {"hidden": [1]}}, LABEL_IDS, 0, "unknown key"),
    ({"tf": GOOD_TF}, LABEL_IDS, 0, "label volume"),
    ({"time": 0}, None, 0, "not a time series"),
    ({"time": 5}, None, 5, "time"),
    ({"time": -1}, None, 5, "time"),
    ({"time": 1.5}, None, 5, "time"),
    ({"time": "2"}, None, 5, "time"),
]


@pytest.mark.parametrize("msg, labels, steps, words", BAD_NEW, ids=[f"badnew{i}" for i in range(len(BAD_NEW))])
def test_bad_new_fields_rejected_with_named_field(msg, labels, steps, words):
    raw = msg if isinstance(msg, str) else json.dumps({"type": "render", **msg})
    with pytest.raises(MessageError) as info:
        parse_message(raw, indices=INDICES, presets=PRESETS, label_ids=labels, steps=steps)
    assert words in str(info.value)
    assert len(str(info.value)) < 400
