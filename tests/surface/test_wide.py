"""The 4-wide BVH's own choices: the float32 box test loses no hit, the SAH collapse fills nodes and keeps every triangle."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast.surface.index as surface_index
from sparsecast.surface import build_bvh, build_rbvh, raycast
from sparsecast.surface._wide_kernels import D_FLUSH, misses_root, root_slab, slab_origins32
from sparsecast.surface.bvh import triangle_tree
from sparsecast.surface.mesh import TriangleMesh, icosphere
from sparsecast.surface.wide import collapse_tree

from .brute import brute_force_hits, rays_at


def _soup(rng, n, offset, size):
    """``n`` small random triangles around ``offset``, with float32 vertices (as the BVH stores them)."""
    c = offset + rng.uniform(-1, 1, (n, 1, 3))
    v = (c + size * rng.normal(size=(n, 3, 3))).astype(np.float32).astype(np.float64)
    return TriangleMesh(v.reshape(-1, 3), np.arange(3 * n).reshape(n, 3), "soup")


def _assert_brute(index, mesh, o, d):
    hits = raycast(index, o, d)
    t_ref, _ = brute_force_hits(mesh.triangles, o, d)
    np.testing.assert_array_equal(hits.hit, np.isfinite(t_ref))
    np.testing.assert_allclose(hits.t[hits.hit], t_ref[hits.hit], rtol=1e-6)
    return hits


def test_float32_origin_rounding_is_directed(rng):
    # Near-plane origin on the side the ray moves to, far-plane origin behind it:
    # entry distances only shrink and exits only grow in float32.
    for o in np.r_[rng.uniform(-1e4, 1e4, 500), 0.0, 1.0, 1e4 + 1e-9]:
        for d in (1.0, -1.0):
            near, far = slab_origins32(o, d)
            assert np.float32(near) == near and np.float32(far) == far  # float32 values
            assert (near >= o) if d > 0 else (near <= o)
            assert (far <= o) if d > 0 else (far >= o)
            assert abs(near - o) <= 4 * np.spacing(np.float32(abs(o)))  # a few ulps at most
        near, far = slab_origins32(o, 0.0)  # in the slab of a face plane through o
        assert far < o < near


def test_rays_near_axis_planes_far_from_the_origin_equal_brute_force(rng):
    # Small triangles at 1000-ish coordinates, where a float32 origin is off by up to
    # 3e-5; direction components of 1e-4 turn that into t errors of 0.3, larger than
    # the triangles: a box test with round-to-nearest origins loses hits here.
    mesh = _soup(rng, 400, np.array([1000.0, -700.0, 300.0]), 0.05)
    index = build_bvh(mesh)
    n = 1500
    o = mesh.triangles[rng.integers(0, mesh.n_triangles, n)].mean(1) + rng.normal(scale=0.02, size=(n, 3))
    d = rng.normal(size=(n, 3))
    small = rng.integers(0, 3, n)
    d[np.arange(n), small] = rng.choice([1e-4, -1e-4, 3e-7, 0.0], n)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = o - 0.5 * d  # a little way back, so the rays cross a few boxes first
    hits = _assert_brute(index, mesh, o, d)
    assert 0.2 < hits.hit.mean() < 0.95


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_ray_leaving_a_box_within_a_float32_ulp_keeps_its_hit(side):
    # A triangle in z = 0 with its box's x face at 1000 (mirrored: -1000); rays start
    # less than half a float32 ulp inside that face, above the triangle, and drift
    # out of the slab slowly enough to hit the triangle first. A float32 origin
    # rounded to nearest sits on the face: the slab ends at t = 0, before the ray
    # reaches z = 0, and the hit is lost.
    x0 = side * 1000.0
    ulp = float(np.spacing(np.float32(1000.0)))
    v = np.array([[x0, 0, 0], [x0 + side, 0, 0], [x0, 1, 0]])
    mesh = TriangleMesh(v, [[0, 1, 2]], "edge")
    delta = np.array([0.3, 0.4, 0.45]) * ulp
    o = np.c_[x0 + side * delta, np.full(3, 0.25), np.ones(3)]
    d = np.c_[-side * delta / 2, np.zeros(3), -np.ones(3)]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = _assert_brute(build_bvh(mesh), mesh, o, d)
    assert hits.hit.all()


def test_tiny_direction_components_equal_brute_force(rng):
    # Components far below a unit vector's rounding are zero for both tests (and
    # 1 / d stays finite in float32).
    mesh = icosphere(3)
    index = build_bvh(mesh)
    d = rng.normal(size=(300, 3))
    d[:100, 0] = 1e-40
    d[100:200, 1] = -1e-25
    d[200:, 2] = 5e-19
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    target = mesh.vertices[rng.integers(0, len(mesh.vertices), 300)] + rng.normal(scale=0.1, size=(300, 3))
    o = target - 3.0 * d
    hits = _assert_brute(index, mesh, o, d)
    assert hits.hit.mean() > 0.5


@pytest.mark.parametrize("c_packet, max_leaf_tris", [(0.25, 16), (1.5, 8), (1.5, 4), (8.0, 8), (1e9, 0)])
def test_collapse_choices_keep_every_triangle_and_equal_brute_force(rng, c_packet, max_leaf_tris):
    mesh = icosphere(3)
    tris = mesh.triangles.astype(np.float32)
    tree = triangle_tree(tris)
    wide = collapse_tree(tree, tris, c_packet=c_packet, max_leaf_tris=max_leaf_tris)
    faces = wide.face4[wide.face4 >= 0]
    np.testing.assert_array_equal(np.sort(faces), np.arange(mesh.n_triangles))
    # Packet lanes hold their face's vertices.
    p, lane = np.nonzero(wide.face4 >= 0)
    np.testing.assert_array_equal(wide.tri4[p, :, lane].reshape(-1, 3, 3), tris[wide.face4[p, lane]])
    # A leaf holds at most max_leaf_tris triangles unless it was a binary leaf already.
    code = -1 - wide.child[wide.child < 0]
    n_pk = (code & 63) + 1
    assert n_pk.max() <= max(1, -(-max(max_leaf_tris, int(tree.count.max())) // 4))
    index = dataclasses.replace(build_bvh(mesh), wide=wide)
    o, d = rays_at(mesh.vertices[rng.integers(0, len(mesh.vertices), 500)], rng, 3.0, jitter=0.3)
    _assert_brute(index, mesh, o, d)


def test_sah_collapse_fills_the_nodes():
    # The greedy collapse (open the largest child) left 2.8 children per node on
    # average on a sphere; the SAH one merges small leaves and fills the slots.
    mesh = icosphere(4)
    w = build_bvh(mesh).wide
    fill = np.isfinite(w.box[:, 0, :]).sum() / len(w.nodes)
    assert fill >= 3.3


def test_a_few_triangles_are_one_leaf():
    mesh = icosphere(0)  # 20 triangles
    tris = mesh.triangles.astype(np.float32)
    tree = triangle_tree(tris)
    w = collapse_tree(tree, tris, max_leaf_tris=32, c_packet=0.01)  # leaves are nearly free: one leaf
    assert len(w.nodes) == 1 and w.n_leaves == 1 and len(w.tri4) == 5
    hits = raycast(dataclasses.replace(build_bvh(mesh), wide=w), [[0, 0, -3]], [[0, 0, 1]])
    assert hits.hit[0]


_COORD = st.floats(-1e4, 1e4, allow_nan=False, allow_subnormal=False)
_COMPONENT = st.one_of(st.floats(-1.0, 1.0, allow_nan=False), st.sampled_from([0.0, 1e-30, -1e-19, 3e-7, -1e-4]))


@settings(max_examples=300, deadline=None)
@given(lo=st.tuples(_COORD, _COORD, _COORD), size=st.tuples(*[st.floats(0.0, 100.0)] * 3),
       corner=st.tuples(*[st.sampled_from([0.0, 1.0, 0.5])] * 3), d=st.tuples(_COMPONENT, _COMPONENT, _COMPONENT),
       t=st.floats(0.0, 1e6), axis=st.integers(0, 2))
def test_root_pretest_never_drops_a_ray_through_the_box(lo, size, corner, d, t, axis):
    # Rays through a point of the box's surface (a corner, an edge, a face: where a
    # hit can be and the pre-test is tightest) at distance t, from any direction with
    # axis-parallel and tiny components among them: the pre-test must let them all
    # through, however far their origin (its float64 rounding is what the pad covers).
    lo = np.array(lo)
    hi = lo + np.array(size)
    p = lo + np.array(corner) * (hi - lo)
    d = np.array(d)
    if np.abs(d).max() < 1e-3:
        d[axis] = 1.0
    d /= np.linalg.norm(d)
    o = p - t * d
    root = root_slab(np.array([lo, hi]))
    assert not misses_root(root, *o, *d, 0.0, np.inf)
    assert not misses_root(root, *o, *d, t, t)  # the point itself, as t_min = t_max
    # ... and a ray that turns away from the box (its far side behind the origin) misses.
    far = p + (1.0 + 1e-3 * (1.0 + np.abs(p).max())) * np.sign(d) * (np.abs(d) > D_FLUSH) * (hi - lo + 1.0)
    if (np.abs(d) > D_FLUSH).any():
        assert misses_root(root, *far, *d, 0.0, np.inf)


def test_root_pretest_keeps_the_ray_interval_and_an_empty_tree_meets_nothing():
    root = root_slab(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]))
    o, d = (0.5, 0.5, -2.0), (0.0, 0.0, 1.0)  # enters at t = 2, leaves at t = 3
    assert not misses_root(root, *o, *d, 0.0, np.inf)
    assert misses_root(root, *o, *d, 0.0, 1.9)  # stops before the box
    assert misses_root(root, *o, *d, 3.1, np.inf)  # starts behind it
    assert not misses_root(root, *o, *d, 2.5, 2.6)
    empty = root_slab(np.array([[np.inf] * 3, [-np.inf] * 3]))
    assert misses_root(empty, *o, *d, 0.0, np.inf) and misses_root(empty, 0.5, 0.5, 0.5, *d, 0.0, np.inf)


@pytest.mark.parametrize("kind", ["bvh", "rbvh"])
def test_rays_grazing_the_root_box_far_from_the_origin_hit_as_without_the_pretest(rng, kind, monkeypatch):
    # A flat square mesh in the plane z = 5000 (its root box has zero thickness there):
    # rays running in that plane, rays with tiny z components, rays touching its edges,
    # from near and from very far (where the watertight test and brute force part ways
    # on edges: not compared here). The pre-test changes no hit: the same rays cast
    # with an infinite root box (the pre-test always passes) give the same results.
    n = 24
    g = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(g, g)
    v = np.c_[1000.0 + x.ravel(), -300.0 + y.ravel(), np.full(x.size, 5000.0)]
    a = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    faces = np.r_[np.c_[a, a + 1, a + n + 2], np.c_[a, a + n + 2, a + n + 1]]
    mesh = TriangleMesh(v, faces, "square")
    index = build_bvh(mesh) if kind == "bvh" else build_rbvh(mesh, "Q2")
    m = 2000
    edge = rng.choice([0.0, 1.0, 0.5, 1e-9], m) + rng.uniform(-1e-6, 1e-6, m) * rng.integers(0, 2, m)
    target = np.c_[1000.0 + edge, -300.0 + rng.uniform(0.0, 1.0, m), np.full(m, 5000.0)]
    d = rng.normal(size=(m, 3))
    d[: m // 4, 2] = 0.0  # in the mesh's plane
    d[m // 4: m // 2, 2] = rng.choice([1e-30, -1e-8, 1e-5], m // 4)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = target - rng.choice([0.5, 1e3, 1e6], m)[:, None] * d
    hits = raycast(index, o, d)
    monkeypatch.setattr(surface_index, "root_slab", lambda root: np.array([-np.inf] * 3 + [np.inf] * 3))
    every = raycast(index, o, d)
    np.testing.assert_array_equal(hits.t, every.t)
    np.testing.assert_array_equal(hits.face, every.face)
    np.testing.assert_array_equal(hits.tile, every.tile)
    assert 0.2 < hits.hit.mean() < 0.9
