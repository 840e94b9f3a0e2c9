"""Label volumes: :meth:`TransferFunction.labels`, nearest sampling, the label JSON format.

Every index equals naive on label scenes in ``tests/index/test_exactness.py``; here
naive equals the NumPy reference with nearest sampling, ids are never blended, and
bad label tables get one clear error.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.errors import ParameterError, TransferFunctionError
from render_helpers import assert_matches_reference
from synthetic import label_volume

RED, GREEN, BLUE = (1.0, 0.0, 0.0, 1.0), (0.0, 1.0, 0.0, 1.0), (0.0, 0.0, 1.0, 1.0)


@st.composite
def label_scenes(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    dtype = draw(st.sampled_from(["uint8", "uint16", "int16", "float32"]))
    shape = tuple(draw(st.integers(2, 24)) for _ in range(3))
    n = draw(st.integers(1, 6))
    vol = label_volume(rng, shape, n, dtype, spacing=tuple(draw(st.sampled_from([0.7, 1.0, 1.6])) for _ in range(3)))
    shown = draw(st.lists(st.integers(0, n + 1), min_size=1, max_size=n + 2, unique=True))
    colours = {i: (draw(st.floats(0, 1)), draw(st.floats(0, 1)), draw(st.floats(0, 1)),
                   draw(st.sampled_from([0.0, 0.3, 1.0]))) for i in shown}
    tf = sc.TransferFunction.labels(colours)
    cam = sc.Camera.orbit(vol, draw(st.sampled_from([0.0, 30.0, 90.0, 200.0])),
                          draw(st.sampled_from([0.0, 20.0, -70.0])),
                          projection=draw(st.sampled_from(["orthographic", "perspective"])))
    return vol, tf, cam, draw(st.sampled_from([0.5, 1.0, 0.37]))


@settings(max_examples=25, deadline=None)
@given(data=label_scenes())
def test_naive_with_labels_equals_the_nearest_reference(data):
    vol, tf, cam, dt = data
    assert tf.sampling == "nearest"
    assert_matches_reference(vol, tf, cam, 14, 12, dt=dt, ert=1.0)


def test_ids_are_never_blended():
    """Opaque labels 1 and 3 side by side: a trilinear lookup would find 2 (green) on
    their boundary; nearest sampling shows red or blue only."""
    data = np.zeros((16, 16, 16), np.uint8)
    data[:, :, 4:8] = 1
    data[:, :, 8:12] = 3
    vol = sc.Volume(data)
    tf = sc.TransferFunction.labels({1: RED, 2: GREEN, 3: BLUE})
    c = vol.center
    cam = sc.Camera.look_at(c + [0, 0, 40], c, up=(0, 1, 0), projection="orthographic", ortho_height=20)
    img = sc.render(vol, tf, cam, 40, 40, index="naive", dt=0.25)
    rgb = img.rgba[..., :3][img.rgba[..., 3] > 0.99]
    assert len(rgb) > 100
    assert rgb[:, 1].max() == 0.0  # no green anywhere
    assert (rgb[:, 0] > 0.99).sum() > 50 and (rgb[:, 2] > 0.99).sum() > 50
    # The same TF as a plain piecewise-linear TF does blend: the test can fail.
    plain = sc.TransferFunction([(0, 0, 0, 0, 0), (0.5, *RED[:3], 0), (1, *RED), (2, *GREEN), (3, *BLUE)], (0, 3))
    blended = sc.render(vol, plain, cam, 40, 40, index="naive", dt=0.25).rgba
    assert blended[..., 1].max() > 0.5


def test_hidden_and_unlisted_labels_are_invisible():
    data = np.zeros((12, 12, 12), np.uint16)
    data[2:10, 2:10, 2:6] = 7
    data[2:10, 2:10, 6:10] = 300
    vol = sc.Volume(data)
    cam = sc.Camera.orbit(vol, 0, 0, projection="orthographic")
    both = sc.TransferFunction.labels({7: RED, 300: BLUE})
    only7 = both.hidden([300])
    assert only7.visible == (7,) and both.visible == (7, 300)
    a = sc.render(vol, both, cam, 24, 24, index="naive").rgba
    b = sc.render(vol, only7, cam, 24, 24, index="naive").rgba
    none = sc.render(vol, sc.TransferFunction.labels({5: RED}), cam, 24, 24, index="naive").rgba
    assert a[..., 2].max() > 0.5 and b[..., 2].max() == 0.0 and b[..., 0].max() > 0.5
    assert none[..., 3].max() == 0.0


def test_ids_given_as_a_list_get_distinct_colours():
    tf = sc.TransferFunction.labels([3, 1, 2, 2], cmap="tab10")
    assert tf.visible == (1, 2, 3)
    cols = {tuple(np.round(tf.labels[i], 6)) for i in tf.visible}
    assert len(cols) == 3
    assert all(c[3] == 1.0 for c in cols)
    half = sc.TransferFunction.labels([1, 2], opacity=0.5)
    assert {c[3] for c in half.labels.values()} == {0.5}


def test_label_tf_does_not_stretch_and_looks_up_nearest():
    tf = sc.TransferFunction.labels({1: RED, 2: GREEN})
    assert tf.with_range((0.0, 1000.0)) is tf
    assert tf.scale == 1.0
    np.testing.assert_array_equal(tf([0, 1, 1.49, 1.5, 2, 3, -4, 70000])[:, 3], [0, 1, 1, 1, 1, 0, 0, 0])


def test_json_round_trip(tmp_path):
    tf = sc.TransferFunction.labels({1: RED, 2: "tab:green", 40: (0.2, 0.4, 1.0, 0.3)}, name="organs [v2]")
    path = tf.save(tmp_path / "labels.json")
    doc = json.loads(path.read_text())
    assert doc["format"] == "sparsecast-labels/1"
    back = sc.TransferFunction.load(path)
    assert isinstance(back, sc.LabelTransferFunction)
    assert back.name == "organs [v2]"
    np.testing.assert_array_equal(back.table, tf.table)


@pytest.mark.parametrize("labels, fragment", [
    ({}, "at least one label"),
    ({"one": RED}, "'one'"),
    ({1.5: RED}, "integer label id"),
    ({1: (1, 0)}, "3 or 4 numbers"),
    ({1: (2, 0, 0)}, "[0, 1]"),
    ({1: "not-a-colour"}, "'not-a-colour'"),
    ({0: RED, 70000: RED}, "at most 65534"),
    ("1,2", "mapping"),
])
def test_bad_label_tables_are_one_clear_error(labels, fragment):
    with pytest.raises(TransferFunctionError) as err:
        sc.TransferFunction.labels(labels)
    assert fragment in str(err.value)


def test_bad_label_json_names_the_file(tmp_path):
    p = tmp_path / "seg[1].json"
    p.write_text(json.dumps({"format": "sparsecast-labels/1", "labels": {"2": [1, 0]}}))
    with pytest.raises(TransferFunctionError, match=r"seg\[1\]\.json: labels\[2\]: expected 3 or 4"):
        sc.TransferFunction.load(p)
    p.write_text(json.dumps({"format": "sparsecast-labels/1", "labels": [1, 2]}))
    with pytest.raises(TransferFunctionError, match="labels: expected an object"):
        sc.TransferFunction.load(p)


def test_approximate_indices_refuse_label_tfs():
    vol = label_volume(np.random.default_rng(0), (10, 10, 10), 2)
    tf = sc.TransferFunction.labels([1, 2])
    cam = sc.Camera.orbit(vol)
    with pytest.raises(ParameterError, match="nearest sampling"):
        sc.render(vol, tf, cam, 8, 8, index="bih", mode="single-sample")
