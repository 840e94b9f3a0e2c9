"""The 4-wide BVH's own choices: the float32 box test loses no hit, the SAH collapse fills nodes and keeps every triangle."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sparsecast.surface import build_bvh, raycast
from sparsecast.surface._wide_kernels import slab_origins32
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
