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
    tf = sc.TransferFunction.labels(colours, smooth=draw(st.booleans()))
    cam = sc.Camera.orbit(vol, draw(st.sampled_from([0.0, 30.0, 90.0, 200.0])),
                          draw(st.sampled_from([0.0, 20.0, -70.0])),
                          projection=draw(st.sampled_from(["orthographic", "perspective"])))
    return vol, tf, cam, draw(st.sampled_from([0.5, 1.0, 0.37]))


@settings(max_examples=25, deadline=None)
@given(data=label_scenes())
def test_naive_with_labels_equals_the_nearest_reference(data):
    """Nearest sampling, and smooth boundaries (the reference blends the corners' labels)."""
    vol, tf, cam, dt = data
    assert tf.sampling == ("smooth-labels" if tf.smooth else "nearest")
    # Smooth opacities are sums of eight weights, which the reference adds in another
    # order: an opaque label's 1.0 may come out an ulp below it, so early termination at
    # exactly 1.0 could stop a ray one sample apart; a threshold below 1 is not that fragile.
    assert_matches_reference(vol, tf, cam, 14, 12, dt=dt, ert=0.99 if tf.smooth else 1.0)


def _two_labels_face_on(z_top: int = 16):
    """Labels 1 (x in [4, 8)) and 3 (x in [8, 12)) below ``z_top``, seen face on along -z
    (orthographic, 40 x 40 pixels of half a voxel: column c looks down x = c / 2 - 2.25)."""
    data = np.zeros((16, 16, 16), np.uint8)
    data[:z_top, :, 4:8] = 1
    data[:z_top, :, 8:12] = 3
    vol = sc.Volume(data)
    c = vol.center
    cam = sc.Camera.look_at(c + [0, 0, 40], c, up=(0, 1, 0), projection="orthographic", ortho_height=20)
    return vol, cam


def test_smooth_labels_blend_neighbours_but_never_other_ids():
    """Face on, a ray at x in (7, 8) sees red and blue weighted by distance (a smooth
    boundary); nearest sampling switches from red to blue at x = 7.5. Green (id 2, between
    1 and 3) never appears either way."""
    vol, cam = _two_labels_face_on()
    tf = sc.TransferFunction.labels({1: RED, 2: GREEN, 3: BLUE})
    smooth = sc.render(vol, tf.smoothed(), cam, 40, 40, index="naive", dt=0.25).rgba
    sharp = sc.render(vol, tf, cam, 40, 40, index="naive", dt=0.25).rgba
    for rgba in (smooth, sharp):
        assert rgba[..., 1].max() == 0.0
    mixed = lambda rgba: int(((rgba[..., 0] > 0.15) & (rgba[..., 2] > 0.15)).sum())  # noqa: E731
    assert mixed(smooth) >= 40 and mixed(sharp) == 0
    # Across the boundary red falls off monotonically in x, through 0.75 at x = 7.25.
    row = smooth[20, 12:26, 0]  # x = 3.75 .. 10.25
    assert np.all(np.diff(row[1:]) <= 1e-6) and row[2] > 0.99 and row[-1] == 0.0
    np.testing.assert_allclose(smooth[20, 19, [0, 2]], [0.75, 0.25], atol=1e-3)


def test_smooth_labels_hidden_neighbours_fade_instead_of_tinting():
    """A visible label next to a hidden one fades out in opacity at the boundary; its
    colour stays its own (straight red), with no trace of the hidden label's colour."""
    vol, cam = _two_labels_face_on(z_top=2)  # two voxels deep: one ray cannot saturate
    tf = sc.TransferFunction.labels({1: (1.0, 0.0, 0.0, 0.2), 3: (0.0, 0.0, 1.0, 0.0)}, smooth=True)
    img = sc.render(vol, tf, cam, 40, 40, index="naive", dt=0.25, ert=1.0).rgba
    assert img[..., 2].max() == 0.0 and img[..., 1].max() == 0.0
    a = img[..., 3]
    row = a[20, 12:26]
    assert np.all(np.diff(row[7:]) <= 1e-6) and row[7] > row[8] > 0.0  # the faded rim at x in (7, 8)
    np.testing.assert_allclose(img[..., 0], a, atol=1e-6)  # premultiplied pure red everywhere


def test_smooth_label_tfs_round_trip_and_keep_smoothness(tmp_path):
    tf = sc.TransferFunction.labels({1: RED, 4: BLUE}, smooth=True)
    back = sc.TransferFunction.load(tf.save(tmp_path / "smooth.json"))
    assert back.smooth and back.sampling == "smooth-labels"
    assert tf.hidden([4]).smooth and tf.with_labels({2: GREEN}).smooth
    assert not tf.smoothed(False).smooth and tf.smoothed(False).sampling == "nearest"
    assert tf.smoothed() is tf
    doc = json.loads((tmp_path / "smooth.json").read_text())
    doc["smooth"] = "yes"
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(TransferFunctionError, match=r"bad\.json: smooth: expected true or false"):
        sc.TransferFunction.load(tmp_path / "bad.json")


def test_smooth_labels_shade_with_the_label_surface():
    """Two opaque grey labels side by side, seen face on: smooth labels shade with the
    gradient of the blended opacity, which points at the viewer all along the face (full
    diffuse plus specular, 0.5 * (ka + kd) + ks = 0.75 with DEFAULT_SHADING); the id
    field's gradient also points across the 1 | 3 boundary, a dark seam there."""
    vol, cam = _two_labels_face_on(z_top=12)
    grey = (0.5, 0.5, 0.5, 1.0)
    tf = sc.TransferFunction.labels({1: grey, 3: grey}, smooth=True)
    smooth = sc.render(vol, tf, cam, 40, 40, index="naive", dt=0.25, shading=True).rgba
    seam = sc.render(vol, tf.smoothed(False), cam, 40, 40, index="naive", dt=0.25, shading=True).rgba
    # x = 5.25 .. 9.75: more than a voxel from the slab's sides, across the 1 | 3 boundary
    np.testing.assert_allclose(smooth[20, 15:25, :3], 0.75, atol=1e-3)
    assert seam[20, 19, 0] < 0.45 and abs(seam[20, 15, 0] - 0.75) < 1e-3  # the seam at x = 7.25, not at x = 5.25
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


@pytest.mark.parametrize("smooth", [False, True])
def test_approximate_indices_and_iso_modes_refuse_label_tfs(smooth):
    vol = label_volume(np.random.default_rng(0), (10, 10, 10), 2)
    tf = sc.TransferFunction.labels([1, 2], smooth=smooth)
    cam = sc.Camera.orbit(vol)
    with pytest.raises(ParameterError, match=f"{tf.sampling} sampling"):
        sc.render(vol, tf, cam, 8, 8, index="bih", mode="single-sample")
    with pytest.raises(ParameterError, match="samples label ids"):
        sc.render(vol, tf, cam, 8, 8, mode="iso", iso=1.0)
