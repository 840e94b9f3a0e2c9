"""The decomposition and the screen rectangles, without a cluster."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.distributed import Layer, decompose, over, screen_rect


@given(st.tuples(st.integers(1, 7), st.integers(1, 7), st.integers(1, 7)), st.integers(1, 9),
       st.integers(0, 2**32 - 1), st.floats(0.0, 1.0))
def test_pieces_tile_the_grid_and_balance_non_empty_bricks(shape, n, seed, density):
    occ = np.random.default_rng(seed).random(shape) < density
    tree = decompose(occ, n, 8)
    cover = np.zeros(shape, np.int32)
    for (x0, y0, z0), (x1, y1, z1) in tree.boxes:
        assert x0 < x1 and y0 < y1 and z0 < z1
        cover[z0:z1, y0:y1, x0:x1] += 1
    assert np.all(cover == 1)  # every brick in exactly one piece: no gap, no overlap
    assert tree.count == min(n, int(np.prod(shape)))  # as many as asked, or one per brick
    assert tree.weights.sum() == occ.sum()
    for p, ((x0, y0, z0), (x1, y1, z1)) in enumerate(tree.boxes):
        assert tree.weights[p] == occ[z0:z1, y0:y1, x0:x1].sum()


def test_balance_follows_the_non_empty_bricks_not_the_volume():
    occ = np.zeros((4, 4, 16), bool)
    occ[:, :, 12:] = True  # everything in the last quarter along x
    tree = decompose(occ, 2, 8)
    assert sorted(tree.weights.tolist()) == [32, 32]
    assert {tuple(b[1] - b[0]) for b in tree.boxes} != {(8, 4, 4)}  # not the half-volume cut


def _rays_hitting(cam, w, h, lo, hi):
    o, d = cam.rays(w, h)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (lo - o) / d
        t1 = (hi - o) / d
    tmin = np.nanmax(np.where(np.isnan(t0), -np.inf, np.minimum(t0, t1)), axis=-1)
    tmax = np.nanmin(np.where(np.isnan(t1), np.inf, np.maximum(t0, t1)), axis=-1)
    return (tmax >= np.maximum(tmin, 0.0)) if cam.projection == "perspective" else (tmax >= tmin)


@settings(max_examples=60)
@given(st.floats(-180, 180), st.floats(-89, 89), st.sampled_from(["perspective", "orthographic"]),
       st.tuples(*[st.floats(0.0, 0.9)] * 3), st.tuples(*[st.floats(0.05, 1.0)] * 3),
       st.sampled_from([0.6, 1.0, 2.5]))
def test_the_screen_rectangle_holds_every_pixel_whose_ray_meets_the_box(az, el, proj, a, size, zoom):
    vol = sc.Volume(np.zeros((30, 20, 40), np.float32), spacing=(1.0, 0.5, 2.0), origin=(3.0, -1.0, 0.0))
    cam = sc.Camera.orbit(vol, az, el, projection=proj, zoom=zoom)
    blo, bhi = (np.asarray(b, float) for b in vol.bounds)
    lo = blo + (bhi - blo) * np.array(a)
    hi = np.minimum(lo + (bhi - blo) * np.array(size), bhi)
    w, h = 64, 48
    hit = _rays_hitting(cam, w, h, lo, hi)
    r = screen_rect(cam, w, h, lo, hi)
    if r is None:
        assert not hit.any()
        return
    x0, y0, rw, rh = r
    inside = np.zeros((h, w), bool)
    inside[y0:y0 + rh, x0:x0 + rw] = True
    assert not (hit & ~inside).any()


def test_a_camera_inside_the_box_sees_it_on_every_pixel():
    vol = sc.Volume(np.zeros((10, 10, 10), np.float32))
    cam = sc.Camera.look_at((4.0, 4.0, 4.0), (9.0, 4.0, 4.0), projection="perspective")
    assert screen_rect(cam, 32, 16, np.zeros(3), np.full(3, 9.0)) == (0, 0, 32, 16)


def test_visibility_order_is_front_to_back_for_the_eye():
    occ = np.ones((1, 1, 4), bool)
    tree = decompose(occ, 4, 8)
    xs = [int(b[0][0]) for b in tree.boxes]
    order_from_left = tree.order(lambda axis, plane: 0.0 < plane * 8)  # eye at x = 0
    assert [xs[p] for p in order_from_left] == sorted(xs)
    order_from_right = tree.order(lambda axis, plane: 40.0 < plane * 8)  # eye beyond the grid
    assert [xs[p] for p in order_from_right] == sorted(xs, reverse=True)


def test_over_is_the_premultiplied_front_to_back_operator_on_the_union_of_rectangles():
    rng = np.random.default_rng(1)

    def layer(x0, y0, w, h):
        a = rng.random((h, w, 1)).astype(np.float32)
        return Layer(x0, y0, np.concatenate([rng.random((h, w, 3)).astype(np.float32) * a, a], -1),
                     np.ones((h, w), np.int32))

    near, far = layer(2, 1, 3, 4), layer(0, 3, 6, 2)
    out = over(near, far)
    full = np.zeros((2, 5, 6, 4), np.float32)
    full[0, 1:5, 2:5] = near.rgba
    full[1, 3:5, 0:6] = far.rgba
    expect = full[0] + (1 - full[0][..., 3:4]) * full[1]
    got = np.zeros((5, 6, 4), np.float32)
    got[out.y0:out.y0 + out.rgba.shape[0], out.x0:out.x0 + out.rgba.shape[1]] = out.rgba
    np.testing.assert_allclose(got, expect, atol=1e-7)
    assert out.samples.sum() == near.samples.sum() + far.samples.sum()
    assert over(None, far) is far and over(near, None) is near


def test_pieces_must_be_a_positive_whole_number():
    with pytest.raises(sc.ParameterError, match="pieces"):
        decompose(np.ones((2, 2, 2), bool), 0, 8)
