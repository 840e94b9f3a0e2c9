"""The deep k-d tree's per-tile leaf lists (kdtree/traversal.py, "Tile lists").

A tile's frustum-culled list must give every ray of the tile exactly the
intervals its own per-ray traversal gives (same leaves, same order, same
floats); images are checked against naive by test_ess_exactness.py. Under a
clip box or clip planes the lists also drop the leaves outside the clip: the
images and non-empty sample counts must still equal naive's.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numba import njit

import sparsecast as sc
from sparsecast.index.interval import make_scratch, next_interval, start_ray, start_tile
from sparsecast.kernels.camera import index_space_ray, tile_corner_rays
from sparsecast.kernels.ray import clip_box
from sparsecast.kernels.tiles import tile_bounds, tile_count

from synthetic import sparse_volume

MAX_INTERVALS = 64


@njit
def _tile_intervals(record, cam, origin, inv_spacing, width, height, box, planes, out, counts, listed, live):
    """Per pixel, the intervals ``next_interval`` yields (``out[py, px, i] = (t0, t1)``);
    per tile, its list length and what ``start_tile`` returned."""
    for tile in range(tile_count(width, height)):
        scratch = make_scratch(record)
        x0, x1, y0, y1 = tile_bounds(tile, width, height)
        live[tile] = start_tile(record, scratch,
                                tile_corner_rays(cam, x0, x1, y0, y1, width, height, origin, inv_spacing),
                                box, planes)
        listed[tile] = scratch[0][0]  # the leaf count (kdtree.traversal._scratch)
        for py in range(y0, y1):
            for px in range(x0, x1):
                r = index_space_ray(cam, px, py, width, height, origin, inv_spacing)
                ray = (r[0], r[1], r[2], r[3], r[4], r[5])
                t_lo, t_hi = clip_box(r[0], r[1], r[2], r[3], r[4], r[5], box[0], box[1], box[2],
                                      box[3], box[4], box[5])
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


def _intervals(idx, vol, cam, width, height, box=None, planes=None):
    """Per-pixel intervals, their counts and each tile's list length; ``box`` (index
    space, default the volume's) and ``planes`` (``(m, 4)``, index space) clip."""
    view_record = idx.traversal_record(None)
    cam_p = np.ascontiguousarray(cam.ray_params(width, height), np.float64)
    origin = np.ascontiguousarray(vol.origin, np.float64)
    inv_spacing = np.ascontiguousarray(1.0 / vol.spacing, np.float64)
    if box is None:
        box = (0.0, 0.0, 0.0) + tuple(float(n - 1) for n in vol.shape[::-1])
    planes = np.zeros((0, 4)) if planes is None else np.ascontiguousarray(planes, np.float64)
    out = np.zeros((height, width, MAX_INTERVALS, 2))
    counts = np.zeros((height, width), np.int64)
    listed = np.zeros(tile_count(width, height), np.int64)
    live = np.zeros(tile_count(width, height), np.bool_)
    _tile_intervals(view_record, cam_p, origin, inv_spacing, width, height, tuple(map(float, box)), planes,
                    out, counts, listed, live)
    assert counts.max() < MAX_INTERVALS
    # start_tile's promise, which lets the driver skip a tile's rays: a tile it calls
    # empty gives no ray an interval (and it calls empty only tiles with empty lists)
    for tile in np.flatnonzero(~live):
        x0, x1, y0, y1 = tile_bounds(tile, width, height)
        assert listed[tile] == 0
        assert counts[y0:y1, x0:x1].sum() == 0, tile
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


def test_empty_tiles_keep_the_initial_rgba_and_count_no_samples(scene):
    # The driver writes the pixels of a tile that start_tile calls empty without
    # setting up their rays: they must still composite `initial` over the background.
    vol, tf = scene
    cam = sc.Camera.orbit(vol, 31.0, 17.0, zoom=0.5)  # the volume small on screen: most tiles empty
    width, height = 64, 56
    idx = sc.build_index(vol, tf, "kdtree-deep")
    _, counts, listed = _intervals(idx, vol, cam, width, height)
    assert np.count_nonzero(listed == 0) > tile_count(width, height) // 2
    init = np.random.default_rng(3).uniform(0.0, 0.5, (height, width, 4)).astype(np.float32)
    init[..., :3] *= init[..., 3:]  # premultiplied
    for kw in (dict(), dict(initial=init, background="white"), dict(mode="iso", iso=0.5)):
        ref = sc.render(vol, tf, cam, width, height, index="naive", **kw)
        img = sc.render(vol, tf, cam, width, height, index="kdtree-deep", **kw)
        assert np.abs(img.rgba - ref.rgba).max() <= 1e-5, kw
        assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"], kw
        assert np.all(img.samples[ref.samples == 0] == 0), kw


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


def _half_box(vol):
    """Index-space box of the volume's lower half in x."""
    nx, ny, nz = (float(n - 1) for n in vol.shape[::-1])
    return (0.0, 0.0, 0.0, 0.5 * nx, ny, nz)


def test_clip_box_and_planes_shorten_the_lists(scene):
    vol, _ = scene
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.05)
    idx = sc.build_index(vol, tf, "kdtree-deep", tile_leaves=4096)  # no tile overflows
    cam = CAMERAS["orthographic"](vol)
    _, _, whole = _intervals(idx, vol, cam, 40, 40)
    _, _, boxed = _intervals(idx, vol, cam, 40, 40, box=_half_box(vol))
    nx = vol.shape[2] - 1
    _, _, planed = _intervals(idx, vol, cam, 40, 40, planes=[(-1.0, 0.0, 0.0, -0.5 * nx)])  # keep x <= nx / 2
    assert np.all(whole >= 0) and np.all(boxed >= 0) and np.all(planed >= 0)
    # culling only removes leaves, and here about half of them
    assert np.all(boxed <= whole) and np.all(planed <= whole)
    assert boxed.sum() < 0.8 * whole.sum() and planed.sum() < 0.8 * whole.sum()


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lo=st.tuples(*[st.floats(-0.2, 0.6)] * 3),
       size=st.tuples(*[st.floats(0.05, 1.2)] * 3), normal=st.tuples(*[st.integers(-2, 2)] * 3),
       cut=st.sampled_from([0.0, 0.5, 0.37]), camera=st.sampled_from(sorted(CAMERAS)))
def test_clipped_tiles_equal_naive(scene, lo, size, normal, cut, camera):
    """Random clip boxes (faces on, between and beyond voxels) and a plane through
    voxel centres, cell centres or neither; every camera, axis-parallel and inside too."""
    vol, tf = scene
    wlo, whi = (np.asarray(b, np.float64) for b in vol.bounds)
    ext = whi - wlo
    box_lo = wlo + np.asarray(lo) * ext
    box_hi = box_lo + np.asarray(size) * ext
    kw = dict(dt=0.5, ert=0.99, clip_box=(tuple(box_lo), tuple(box_hi)))
    if any(normal):
        o = np.asarray(vol.origin, np.float64)
        centre = o + (np.round((vol.center - o) / vol.spacing) + cut) * vol.spacing  # through the lattice
        kw["clip_planes"] = [(tuple(centre), tuple(float(v) for v in normal))]
    cam = CAMERAS[camera](vol)
    ref = sc.render(vol, tf, cam, 21, 19, index="naive", **kw)
    for tile_leaves in (None, 3):
        opts = {} if tile_leaves is None else {"tile_leaves": tile_leaves}
        img = sc.render(vol, tf, cam, 21, 19, index=sc.build_index(vol, tf, "kdtree-deep", **opts), **kw)
        assert np.abs(img.rgba - ref.rgba).max() <= 1e-5, tile_leaves
        assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"]


def test_leaves_just_inside_a_clip_face_stay():
    """Clip faces swept through the volume in quarter voxels, seen head-on: the samples
    right behind each face are the first a ray takes, so a leaf culled that only just
    reaches inside the clip shows in the image."""
    vol = sparse_volume(np.random.default_rng(5), (30, 34, 40), 40)  # blobs cut by most faces
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.05)
    lo, hi = (np.asarray(b, np.float64) for b in vol.bounds)
    sx = float(vol.spacing[0])
    idx = sc.build_index(vol, tf, "kdtree-deep", tile_leaves=4096)  # every tile uses its list
    assert idx.n_leaves > 20
    for side in (-1.0, 1.0):
        c = vol.center
        eye = c + side * np.array([vol.diagonal, 0.0, 0.0])
        cam = sc.Camera.look_at(eye, c, up=(0, 0, 1), projection="orthographic", ortho_height=vol.diagonal * 0.9)
        for face in np.arange(0.3, 0.7, 0.0625):
            cut = lo[0] + face * (hi[0] - lo[0]) + 0.13 * sx
            box = ((cut, lo[1], lo[2]), tuple(hi)) if side < 0 else (tuple(lo), (cut, hi[1], hi[2]))
            plane = [((cut, 0.0, 0.0), (-side, 0.0, 0.0))]
            for kw in (dict(clip_box=box), dict(clip_planes=plane)):
                ref = sc.render(vol, tf, cam, 32, 32, dt=0.5, index="naive", **kw)
                img = sc.render(vol, tf, cam, 32, 32, dt=0.5, index=idx, **kw)
                assert np.abs(img.rgba - ref.rgba).max() <= 1e-5, (side, face, sorted(kw))
                assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"]
