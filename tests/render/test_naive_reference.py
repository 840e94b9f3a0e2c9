"""The naive marcher against the independent NumPy reference (``tests/reference.py``, written
from the contract without the Numba kernels): images to 1e-5 per channel, sample counts exactly.

Every scene runs on float32 and uint8 volumes; each other supported dtype (uint16, int16,
float64) renders a few scenes only, as each dtype compiles the marcher once more.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from hypothesis import given, settings

import sparsecast as sc
from sparsecast import Camera, TransferFunction, Volume
from render_helpers import assert_matches_reference, random_volume, make_tfs, camera_set, scenes, _CAMERA_NAMES, _ORIGIN, _SHAPE, _SPACING
from reference import expected_sample_count


# ---------------------------------------------------------------------------------
# naive renderer vs reference
# ---------------------------------------------------------------------------------
@pytest.mark.parametrize("camera_name", _CAMERA_NAMES)
@pytest.mark.parametrize("dtype", ["float32", "uint8"])
def test_naive_matches_reference(dtype, camera_name):
    rng = np.random.default_rng(zlib.crc32(f"{dtype}/{camera_name}".encode()))
    vol = random_volume(rng, _SHAPE, dtype, spacing=_SPACING, origin=_ORIGIN)
    vr = (0.0, 255.0) if dtype == "uint8" else (0.0, 1.0)
    cam = camera_set(vol)[camera_name]
    settings_ = [
        dict(dt=0.37, ert=0.99, background="transparent"),
        dict(dt=0.5, ert=1.0, background=(0.2, 0.3, 0.4, 0.6)),
        dict(dt=1.3, ert=0.6, background="white"),
    ]
    for tf, kw in zip(make_tfs(vr), settings_):
        assert_matches_reference(vol, tf, cam, 16, 12, **kw)


#: the other supported dtypes, with values as such data comes: 12-bit CT stored in uint16,
#: CT in Hounsfield units (negative, air at -1024) in int16, a signed float64 field
_OTHER_DTYPES = {
    "uint16": lambda v: np.rint(v * 4095.0).astype(np.uint16),
    "int16": lambda v: np.rint(v * 4095.0 - 1024.0).astype(np.int16),
    "float64": lambda v: v * 3.0 - 0.75,
}


@pytest.mark.parametrize("camera_name", ["orbit-persp-az30-el20", "orbit-ortho-az45-el89.9",
                                         "axis-y-ortho", "inside-persp"])
@pytest.mark.parametrize("dtype", list(_OTHER_DTYPES))
def test_naive_matches_reference_other_dtypes(dtype, camera_name):
    rng = np.random.default_rng(zlib.crc32(f"{dtype}/{camera_name}".encode()))
    vals = rng.random(_SHAPE) * (rng.random(_SHAPE) < 0.6)
    vol = Volume(_OTHER_DTYPES[dtype](vals), spacing=_SPACING, origin=_ORIGIN)
    assert vol.dtype == np.dtype(dtype)
    lo, hi = vol.value_range
    assert lo < 0.0 if dtype != "uint16" else lo == 0.0  # negative voxels where the dtype has them
    cam = camera_set(vol)[camera_name]
    for tf, kw in zip(make_tfs((lo, hi)), [dict(dt=0.37, ert=0.99), dict(dt=0.5, ert=1.0, background="white"),
                                          dict(dt=1.3, ert=0.6)]):
        img, _ = assert_matches_reference(vol, tf, cam, 16, 12, **kw)
        assert img.rgba[..., 3].max() > 0.5  # something visible: the comparison means something


def test_default_dt_matches_reference(rng):
    vol = random_volume(rng, _SHAPE, "float32", spacing=_SPACING, origin=_ORIGIN)
    tf = TransferFunction.preset("magma", (0.0, 1.0))
    img = assert_matches_reference(vol, tf, Camera.orbit(vol, 20, 30), 13, 17)[0]
    assert img.stats["dt"] == pytest.approx(0.5 * min(_SPACING))


# ---------------------------------------------------------------------------------
# analytic case: constant density, constant opacity
# ---------------------------------------------------------------------------------
def _constant_scene(c=0.6, a=0.3, color=(0.2, 0.6, 0.9)):
    """8 x 8 x 6 voxels, spacing (1, 1, 2), origin (0, 0, 1), seen along +z by an
    8 x 8 orthographic camera whose pixel centres sit exactly on the voxel columns
    x, y in {0, ..., 7} (so the outermost rays lie exactly on the box faces)."""
    vol = Volume(np.full((6, 8, 8), c, np.float32), spacing=(1.0, 1.0, 2.0), origin=(0.0, 0.0, 1.0))
    tf = TransferFunction([(0.0, *color, a), (1.0, *color, a)])
    cam = Camera.look_at((3.5, 3.5, -9.0), (3.5, 3.5, 0.0), up=(0.0, 1.0, 0.0),
                         projection="orthographic", ortho_height=8.0)
    # Index-space box in z is [0, 5]; world z from 1 to 11; the eye is at z = -9.
    t_near, t_far = 10.0, 20.0
    return vol, tf, cam, t_near, t_far


@pytest.mark.parametrize("dt", [0.5, 0.3, 1.0, 2.5])
def test_constant_volume_analytic(dt):
    a, color = 0.3, np.array([0.2, 0.6, 0.9])
    vol, tf, cam, t_near, t_far = _constant_scene(a=a, color=tuple(color))
    n = expected_sample_count(t_near, t_far, dt)
    # (t_near, t_far and the binary dt values are exact; 10/0.3 and 20/0.3 are far from integers)
    img = sc.render(vol, tf, cam, 8, 8, dt=dt, ert=1.0)
    assert np.all(img.samples == n), f"expected {n} samples on every ray, got {np.unique(img.samples)}"
    a_corr = 1.0 - (1.0 - a) ** (dt / 1.0)  # unit distance = min spacing = 1
    alpha = 1.0 - (1.0 - a_corr) ** n
    np.testing.assert_allclose(img.rgba[..., 3], alpha, atol=1e-6)
    np.testing.assert_allclose(img.rgba[..., :3], np.broadcast_to(color * alpha, (8, 8, 3)), atol=1e-6)
    # and the reference agrees
    assert_matches_reference(vol, tf, cam, 8, 8, dt=dt, ert=1.0)


def test_constant_volume_early_termination():
    a, dt, ert = 0.3, 0.5, 0.5
    vol, tf, cam, t_near, t_far = _constant_scene(a=a)
    n_total = expected_sample_count(t_near, t_far, dt)
    a_corr = float(tf.opacity_table(dt, 1.0)[0, 3])
    acc, n_stop, prev = 0.0, 0, 0.0
    while n_stop < n_total and acc < ert:
        prev = acc
        acc += (1.0 - acc) * a_corr
        n_stop += 1
    assert n_stop < n_total and prev < ert <= acc  # the scene does terminate early
    img = sc.render(vol, tf, cam, 8, 8, dt=dt, ert=ert)
    assert np.all(img.samples == n_stop)
    alpha = img.rgba[..., 3]
    np.testing.assert_allclose(alpha, 1.0 - (1.0 - a_corr) ** n_stop, atol=1e-6)
    assert np.all(alpha >= ert - 1e-6)
    assert np.all(alpha < 1.0 - (1.0 - a_corr) ** (n_stop + 1))
    assert_matches_reference(vol, tf, cam, 8, 8, dt=dt, ert=ert)


@pytest.mark.parametrize("ert", [1.0, 0.99])
def test_fully_opaque_sample_stops_ray(ert):
    """A sample of opacity 1 makes A == 1 >= ert, so the next sample is never taken,
    even with ert = 1.0 (termination is tested *before* each sample)."""
    vol, _, cam, _, _ = _constant_scene()
    tf = TransferFunction([(0.0, 0.5, 0.5, 0.5, 1.0)], value_range=(0.0, 1.0))
    img, _ = assert_matches_reference(vol, tf, cam, 8, 8, dt=0.5, ert=ert)
    assert np.all(img.samples == 1)
    assert np.all(img.rgba[..., 3] == 1.0)


def test_rays_on_box_faces_hit():
    """Axis-parallel rays lying exactly in a face plane of the box still sample it."""
    vol, tf, cam, t_near, t_far = _constant_scene()
    img = sc.render(vol, tf, cam, 8, 8, dt=0.5)
    assert np.all(img.samples > 0)
    # one pixel outside on each side: extend the view to 10 x 10 pixels, 10 units
    cam10 = Camera.look_at((3.5, 3.5, -9.0), (3.5, 3.5, 0.0), up=(0.0, 1.0, 0.0),
                           projection="orthographic", ortho_height=10.0)
    img10 = sc.render(vol, tf, cam10, 10, 10, dt=0.5, ert=1.0)
    inside = np.zeros((10, 10), bool)
    inside[1:9, 1:9] = True
    assert np.all(img10.samples[inside] == 21)
    assert np.all(img10.samples[~inside] == 0)
    assert np.all(img10.rgba[~inside] == 0.0)





@given(scenes())
def test_property_render_matches_reference(scene):
    vol, tf, cam, w, h, kw = scene
    img, ref = assert_matches_reference(vol, tf, cam, w, h, **kw)
    rgba = img.rgba
    assert np.all(np.isfinite(rgba))
    assert rgba.min() >= -1e-6 and rgba.max() <= 1.0 + 1e-6
    # premultiplied: colour never exceeds opacity
    assert np.all(rgba[..., :3] <= rgba[..., 3:4] + 1e-6)
    assert np.all(img.samples >= 0)


@settings(max_examples=10, deadline=None)
@given(scenes())
def test_property_shading_changes_colour_only(scene):
    """The reference is unshaded; with shading on, opacity and sample counts must not
    change, and colours stay premultiplied and in range."""
    vol, tf, cam, w, h, kw = scene
    plain = sc.render(vol, tf, cam, w, h, **kw)
    lit = sc.render(vol, tf, cam, w, h, shading=True, **kw)
    np.testing.assert_array_equal(lit.rgba[..., 3], plain.rgba[..., 3])
    np.testing.assert_array_equal(lit.samples, plain.samples)
    assert np.all(np.isfinite(lit.rgba))
    assert lit.rgba.min() >= -1e-6 and lit.rgba.max() <= 1.0 + 1e-6
    assert np.all(lit.rgba[..., :3] <= lit.rgba[..., 3:4] + 1e-6)





# ---------------------------------------------------------------------------------
# real data
# ---------------------------------------------------------------------------------
def test_mni152_matches_reference(shared_file):
    path = shared_file("mni152_t1_197x233x189_uint8.nrrd")
    vol = sc.load_volume(path)
    assert vol.dims == (197, 233, 189) and vol.dtype == np.uint8
    tf = TransferFunction.preset("bone", vol.value_range)
    for az, el in [(0, 0), (30, 20)]:
        cam = Camera.orbit(vol, az, el, projection="orthographic")
        img, _ = assert_matches_reference(vol, tf, cam, 48, 48, dt=2.0)
        assert img.rgba[..., 3].max() > 0.5  # the head is visible


