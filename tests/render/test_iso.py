"""Isosurfaces: ``render(mode="iso" | "iso+dvr", iso=...)``.

Naive equals the per-ray Python reference (``reference.reference_iso``); every exact
index equals naive in ``tests/index/test_exactness.py``. Here: the contract on
generated scenes, skipping, defaults and bad input.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.errors import ParameterError
from reference import reference_iso
from synthetic import sparse_volume

ATOL = 1e-5


@st.composite
def iso_scenes(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    shape = tuple(draw(st.integers(3, 16)) for _ in range(3))
    vol = sparse_volume(rng, shape, draw(st.integers(1, 4)), draw(st.sampled_from(["float32", "uint8"])),
                        spacing=tuple(draw(st.sampled_from([0.8, 1.0, 1.5])) for _ in range(3)))
    lo, hi = vol.value_range
    if hi <= lo:
        hi = lo + 1.0
    m = draw(st.integers(1, 3))
    # Isovalues anywhere in the range, some exactly on voxel values.
    vox = np.unique(vol.data)
    values = [float(draw(st.sampled_from(list(vox)))) if draw(st.booleans())
              else lo + (hi - lo) * draw(st.floats(0.05, 0.95)) for _ in range(m)]
    colors = [(draw(st.floats(0, 1)), draw(st.floats(0, 1)), draw(st.floats(0, 1)),
               draw(st.sampled_from([1.0, 0.5, 0.25]))) for _ in range(m)]
    tf = sc.TransferFunction.preset("viridis", (lo, hi), threshold=draw(st.sampled_from([0.3, 0.6])))
    cam = sc.Camera.orbit(vol, draw(st.sampled_from([0.0, 30.0, 90.0, 222.0])),
                          draw(st.sampled_from([0.0, 25.0, -70.0])),
                          projection=draw(st.sampled_from(["orthographic", "perspective"])))
    return vol, tf, cam, values, colors, draw(st.sampled_from([0.5, 0.9]))


@settings(max_examples=20, deadline=None)
@given(data=iso_scenes(), dvr=st.booleans())
def test_naive_iso_equals_the_reference(data, dvr):
    vol, tf, cam, values, colors, dt = data
    mode = "iso+dvr" if dvr else "iso"
    img = sc.render(vol, tf, cam, 10, 9, index="naive", mode=mode, iso=values, iso_colors=colors, dt=dt,
                    shading=False, ert=1.0)
    ref = reference_iso(vol, tf, cam, 10, 9, values, colors, dt=dt, ert=1.0, dvr=dvr)
    np.testing.assert_allclose(img.rgba, ref, atol=ATOL)


def _sphere(n=40, r=12.0):
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float32)
    c = (n - 1) / 2
    return sc.Volume(np.clip(1.0 - np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2) / (2 * r), 0, 1))


def test_a_sphere_is_a_disc_and_skipping_takes_fewer_samples():
    vol = _sphere()
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    cam = sc.Camera.orbit(vol, 0, 0, projection="orthographic")
    naive = sc.render(vol, tf, cam, 48, 48, index="naive", mode="iso", iso=0.5)
    fast = sc.render(vol, tf, cam, 48, 48, index="kdtree-deep", mode="iso", iso=0.5)
    np.testing.assert_allclose(fast.rgba, naive.rgba, atol=ATOL)
    assert fast.stats["samples"] < 0.5 * naive.stats["samples"]
    assert naive.stats["shading"] and naive.stats["mode"] == "iso"  # iso shades by default
    hit = naive.rgba[..., 3] > 0.99
    # f = 0.5 at distance r = 12 from the centre: rays passing closer hit, farther ones miss.
    o, d = cam.rays(48, 48)
    rel = vol.center - o
    miss_dist = np.linalg.norm(rel - (rel * d).sum(-1, keepdims=True) * d, axis=-1)
    assert hit[miss_dist < 11.0].all() and not hit[miss_dist > 13.0].any()
    assert hit.sum() > 50
    # Shading: the rim is darker than the centre of the disc.
    lum = naive.rgba[..., :3].sum(-1)
    assert lum[24, 24] > lum[hit].min() + 0.1


def test_translucent_surfaces_show_what_is_behind():
    vol = _sphere()
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    cam = sc.Camera.orbit(vol, 0, 0, projection="orthographic")
    outer_only = sc.render(vol, tf, cam, 32, 32, index="naive", mode="iso", iso=[0.4],
                           iso_colors=[(1, 0, 0, 0.5)], shading=False)
    both = sc.render(vol, tf, cam, 32, 32, index="naive", mode="iso", iso=[0.4, 0.7],
                     iso_colors=[(1, 0, 0, 0.5), (0, 0, 1, 1)], shading=False)
    c = both.rgba[16, 16]
    assert outer_only.rgba[16, 16, 2] == 0.0 and c[2] > 0.2 and c[0] > 0.4  # blue seen through red
    # Leaving the sphere crosses 0.4 again (the back side): alpha 1 - 0.5^2 with the outer one alone.
    np.testing.assert_allclose(outer_only.rgba[16, 16, 3], 0.75, atol=1e-6)


def test_isovalue_outside_the_data_is_a_background_image():
    vol = _sphere()
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    img = sc.render(vol, tf, sc.Camera.orbit(vol), 16, 16, mode="iso", iso=3.0, index="grid-pc")
    assert img.rgba.max() == 0.0 and img.stats["samples"] == 0


@pytest.mark.parametrize("kw, fragment", [
    (dict(mode="iso"), "needs isovalues"),
    (dict(mode="iso", iso=[]), "1 to 8"),
    (dict(mode="iso", iso=list(range(9))), "1 to 8"),
    (dict(mode="iso", iso=float("nan")), "finite"),
    (dict(mode="iso", iso="x"), "iso"),
    (dict(iso=0.5), "only with mode='iso'"),
    (dict(mode="iso", iso=[0.2, 0.5], iso_colors=[(1, 0, 0)]), "2 colour(s)"),
    (dict(mode="iso", iso=0.5, iso_colors=[(1, 0, 2)]), "[0, 1]"),
    (dict(mode="surface", iso=0.5), "mode"),
])
def test_bad_iso_input_is_one_clear_error(kw, fragment):
    vol = _sphere(12, 3.0)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    with pytest.raises(ParameterError) as err:
        sc.render(vol, tf, sc.Camera.orbit(vol), 8, 8, **kw)
    assert fragment in str(err.value)


def test_approximate_and_prebuilt_indices_refuse_iso():
    vol = _sphere(12, 3.0)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    bih = sc.build_index(vol, tf, "bih", mode="single-sample")
    with pytest.raises(ParameterError, match="index"):
        sc.render(vol, tf, sc.Camera.orbit(vol), 8, 8, index=bih, mode="iso", iso=0.5)


def test_an_index_built_for_the_spiked_tf_is_reused_in_iso_modes():
    from sparsecast.render import classification_tf

    vol = _sphere()
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    cam = sc.Camera.orbit(vol, 20, 10)
    for mode in ("iso", "iso+dvr"):
        idx = sc.build_index(vol, classification_tf(tf, mode, [0.5]), "grid-pc", cell=4)
        reused = sc.render(vol, tf, cam, 24, 24, index=idx, mode=mode, iso=0.5)
        named = sc.render(vol, tf, cam, 24, 24, index="grid-pc", cell=4, mode=mode, iso=0.5)
        naive = sc.render(vol, tf, cam, 24, 24, index="naive", mode=mode, iso=0.5)
        np.testing.assert_allclose(reused.rgba, naive.rgba, atol=ATOL)
        assert reused.stats["build_ms"] == 0.0 and reused.stats["samples"] == named.stats["samples"]
        if mode == "iso":  # (iso+dvr keeps the TF's opacity: the sphere is non-empty throughout)
            assert reused.stats["samples"] < naive.stats["samples"]
    # In iso mode the classification ignores the TF's opacity: another preset reuses it.
    other = sc.TransferFunction.preset("magma", (0.0, 1.0), threshold=0.7)
    idx = sc.build_index(vol, classification_tf(tf, "iso", [0.5]), "grid-pc")
    sc.render(vol, other, cam, 8, 8, index=idx, mode="iso", iso=0.5)
    # An index for other isovalues, or for the DVR TF, would skip surfaces: refused.
    for wrong in (sc.build_index(vol, classification_tf(tf, "iso", [0.3]), "grid-pc"),
                  sc.build_index(vol, tf, "grid-pc")):
        with pytest.raises(ParameterError, match="built for its isovalues"):
            sc.render(vol, tf, cam, 8, 8, index=wrong, mode="iso", iso=0.5)


def test_label_tfs_refuse_iso():
    vol = sc.Volume(np.zeros((6, 6, 6), np.uint8))
    with pytest.raises(ParameterError, match="label ids"):
        sc.render(vol, sc.TransferFunction.labels([1]), sc.Camera.orbit(vol), 8, 8, mode="iso", iso=0.5)


def test_bih_build_modes_still_pass_through_render():
    vol = _sphere(16, 4.0)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    img = sc.render(vol, tf, sc.Camera.orbit(vol), 8, 8, index="bih", mode="single-sample")
    assert img.stats["mode"] == "dvr" and img.stats["index"] == "bih"


def test_the_first_iso_frame_after_dvr_warms_up_outside_the_timing():
    """The driver compiles per mode: an iso frame with an index kind that DVR already
    warmed must be warmed under its own key (jit_ms), not compiled inside stats["ms"]
    (before, the viewer's first isosurface frame on bonsai took 10 s of "frame" time)."""
    from sparsecast.kernels.iso import Iso
    from sparsecast.kernels.march import Dvr
    from sparsecast.render import local as api

    vol = _sphere(16, 4.0)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    cam = sc.Camera.orbit(vol)
    sc.render(vol, tf, cam, 8, 8, index="grid-mm")
    sc.render(vol, tf, cam, 8, 8, index="grid-mm", mode="iso", iso=0.5)
    record = type(sc.build_index(vol, tf, "grid-mm").traversal_record(api._view(
        np.asarray(cam.ray_params(8, 8), np.float64), vol.origin, 1.0 / vol.spacing)))
    warmed = {k[-1] for k in api._WARM if k[0] is record and k[1] == vol.data.dtype.str}
    assert {Dvr, Iso} <= warmed
