"""The deep k-d tree's per-tile leaf lists (kdtree/traversal.py, "Tile lists").

A tile's frustum-culled list must give every ray of the tile exactly the
intervals its own per-ray traversal gives (same leaves, same order, same
floats); images are checked against naive by test_ess_exactness.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

import sparsecast as sc
from sparsecast.index.interval import make_scratch, next_interval, start_ray, start_tile
from sparsecast.kernels.camera import index_space_ray
from sparsecast.kernels.ray import clip_box
from sparsecast.kernels.tiles import tile_bounds, tile_count

from synthetic import sparse_volume

MAX_INTERVALS = 64


@njit
def _tile_intervals(record, cam, origin, inv_spacing, width, height, box_hi, out, counts, listed):
    """Per pixel, the intervals ``next_interval`` yields (``out[py, px, i] = (t0, t1)``)."""
    for tile in range(tile_count(width, height)):
        scratch = make_scratch(record)
        x0, x1, y0, y1 = tile_bounds(tile, width, height)
        a = index_space_ray(cam, x0, y0, width, height, origin, inv_spacing)
        b = index_space_ray(cam, x1 - 1, y0, width, height, origin, inv_spacing)
        c = index_space_ray(cam, x1 - 1, y1 - 1, width, height, origin, inv_spacing)
        e = index_space_ray(cam, x0, y1 - 1, width, height, origin, inv_spacing)
        start_tile(record, scratch, ((a[0], a[1], a[2], a[3], a[4], a[5]), (b[0], b[1], b[2], b[3], b[4], b[5]),
                                     (c[0], c[1], c[2], c[3], c[4], c[5]), (e[0], e[1], e[2], e[3], e[4], e[5])))
        listed[tile] = scratch[0]
        for py in range(y0, y1):
            for px in range(x0, x1):
                r = index_space_ray(cam, px, py, width, height, origin, inv_spacing)
                ray = (r[0], r[1], r[2], r[3], r[4], r[5])
                t_lo, t_hi = clip_box(r[0], r[1], r[2], r[3], r[4], r[5], 0.0, 0.0, 0.0,
                                      box_hi[0], box_hi[1], box_hi[2])
                t_lo = max(t_lo, 0.0)
                n = 0
                if t_lo <= t_hi:
                    state = start_ray(record, scratch, ray, t_lo, t_hi)
                    while n < MAX_INTERVALS:
                        t0, t1, state = next_interval(record, scratch, ray, state, -math.inf)
                        if t0 > t1:
                            break
                        out[py, px, n, 0] = t0
                        out[py, px, n, 1] = t1
                        n += 1
                counts[py, px] = n


def _intervals(idx, vol, cam, width, height):
    view_record = idx.traversal_record(None)
    cam_p = np.ascontiguousarray(cam.ray_params(width, height), np.float64)
    origin = np.ascontiguousarray(vol.origin, np.float64)
    inv_spacing = np.ascontiguousarray(1.0 / vol.spacing, np.float64)
    box_hi = np.array(vol.shape[::-1], np.float64) - 1
    out = np.zeros((height, width, MAX_INTERVALS, 2))
    counts = np.zeros((height, width), np.int64)
    listed = np.zeros(tile_count(width, height), np.int64)
    _tile_intervals(view_record, cam_p, origin, inv_spacing, width, height, box_hi, out, counts, listed)
    assert counts.max() < MAX_INTERVALS
    return out, counts, listed


@pytest.fixture(scope="module")
def scene():
    vol = sparse_volume(np.random.default_rng(11), (37, 44, 51), 10)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.3)
    return vol, tf


CAMERAS = {
    "perspective": lambda vol: sc.Camera.orbit(vol, 31.0, 17.0),
    "orthographic": lambda vol: sc.Camera.orbit(vol, -58.0, 41.0, projection="orthographic"),
    "axis-parallel": lambda vol: sc.Camera.orbit(vol, 0.0, 0.0, projection="orthographic"),
    "inside": lambda vol: sc.Camera.orbit(vol, 20.0, 10.0, distance=0.15 * vol.diagonal),
    "close-up": lambda vol: sc.Camera.orbit(vol, 200.0, -30.0, zoom=4.0),
}


@pytest.mark.parametrize("camera", sorted(CAMERAS))
def test_tile_lists_give_each_ray_its_own_intervals(scene, camera):
    vol, tf = scene
    cam = CAMERAS[camera](vol)
    width, height = 45, 38  # ragged tiles on the right and bottom edges
    per_ray = sc.build_index(vol, tf, "kdtree-deep", tile_leaves=0)
    tiled = sc.build_index(vol, tf, "kdtree-deep")
    assert per_ray.tile_leaves == 0 and tiled.tile_leaves > 0
    ref, ref_n, ref_listed = _intervals(per_ray, vol, cam, width, height)
    got, got_n, listed = _intervals(tiled, vol, cam, width, height)
    assert np.all(ref_listed == -1)
    # some tiles do use their lists, and the lists cull: fewer leaves than the tree's
    assert np.any(listed >= 0) and listed.max() < tiled.n_leaves
    assert ref_n.sum() > 0
    np.testing.assert_array_equal(got_n, ref_n)
    np.testing.assert_array_equal(got, ref)


def test_a_full_list_falls_back_to_per_ray_traversal(scene):
    vol, tf = scene
    cam = CAMERAS["perspective"](vol)
    per_ray = sc.build_index(vol, tf, "kdtree-deep", tile_leaves=0)
    tiny = sc.build_index(vol, tf, "kdtree-deep", tile_leaves=2)
    ref, ref_n, _ = _intervals(per_ray, vol, cam, 40, 40)
    got, got_n, listed = _intervals(tiny, vol, cam, 40, 40)
    assert np.any(listed == -1) and np.any(listed >= 0)  # both modes in one frame
    np.testing.assert_array_equal(got_n, ref_n)
    np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize("tile_leaves", [0, 1, 48])
def test_images_equal_naive_for_any_list_size(scene, tile_leaves):
    vol, tf = scene
    for camera in ("perspective", "inside", "axis-parallel"):
        cam = CAMERAS[camera](vol)
        ref = sc.render(vol, tf, cam, 40, 33, index="naive")
        idx = sc.build_index(vol, tf, "kdtree-deep", tile_leaves=tile_leaves)
        img = sc.render(vol, tf, cam, 40, 33, index=idx)
        assert np.abs(img.rgba - ref.rgba).max() <= 1e-5, camera
        assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"], camera


def test_tile_leaves_is_checked(scene):
    vol, tf = scene
    with pytest.raises(sc.ParameterError, match="tile_leaves"):
        sc.build_index(vol, tf, "kdtree-deep", tile_leaves=-1)
