"""The exact triangle BVH, in both traversal layouts, against brute force; raycast's input checks."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparsecast.errors import ParameterError
from sparsecast.surface import build_bvh, raycast
from sparsecast.io.meshes import load_mesh
from sparsecast.surface.bvh import LAYOUTS
from sparsecast.surface.mesh import TriangleMesh, icosphere

from .brute import brute_force_hits, rays_at

layouts = pytest.mark.parametrize("layout", LAYOUTS)


def _check_against_brute(mesh: TriangleMesh, origins, dirs, **kw):
    index = build_bvh(mesh, **kw)
    hits = raycast(index, origins, dirs)
    t_ref, f_ref = brute_force_hits(mesh.triangles, origins, dirs)
    np.testing.assert_array_equal(hits.hit, np.isfinite(t_ref))
    both = hits.hit
    np.testing.assert_allclose(hits.t[both], t_ref[both], rtol=1e-5, atol=1e-5)
    # Where the nearest triangle is unambiguous the face must match too.
    tri_t = hits.t[both]
    differ = int((hits.face[both] != f_ref[both]).sum())
    assert differ <= max(1, 0.01 * both.sum()), f"{differ} faces disagree (ties at shared edges aside)"
    assert np.all(hits.tile == -1)
    np.testing.assert_allclose(hits.points[both], origins[both] + tri_t[:, None] * dirs[both], atol=1e-5)
    return index, hits


@layouts
def test_sphere_rays_equal_brute_force(rng, layout):
    mesh = icosphere(3)
    o, d = rays_at(mesh.vertices[rng.integers(0, len(mesh.vertices), 600)], rng, 3.0, jitter=0.4)
    index, hits = _check_against_brute(mesh, o, d, layout=layout)
    assert 0.3 < hits.hit.mean() < 1.0  # both hits and misses are exercised
    s = index.stats()
    assert s["layout"] == layout and s["triangles"] == mesh.n_triangles and s["tiles"] == 0
    if layout == "binary":
        assert s["nodes"] >= 2 * s["triangle_leaves"] - 1
    else:
        # Every node but the root fills a child slot; four slots per node.
        assert s["nodes"] - 1 + s["triangle_leaves"] <= 4 * s["nodes"]
        assert s["nodes"] < s["triangle_leaves"]  # wide: fewer nodes than leaves


@settings(max_examples=8)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 300), max_leaf=st.sampled_from([1, 4, 8]),
       layout=st.sampled_from(LAYOUTS))
def test_random_soup_equals_brute_force(seed, n, max_leaf, layout):
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-1, 1, (n, 1, 3))
    tris = centers + 0.3 * rng.normal(size=(n, 3, 3))
    mesh = TriangleMesh(tris.reshape(-1, 3), np.arange(3 * n).reshape(n, 3), "soup")
    o = rng.uniform(-2, 2, (200, 3))
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    _check_against_brute(mesh, o, d, max_leaf=max_leaf, layout=layout)


@layouts
def test_axis_parallel_rays_hit_axis_aligned_faces(layout):
    # Zero direction components must not turn box tests into NaN.
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], "tri")
    hits = raycast(build_bvh(mesh, layout=layout), [[0.25, 0.25, 1.0], [0.0, 0.0, 1.0]], [[0, 0, -1], [0, 0, -1]])
    np.testing.assert_allclose(hits.t, [1.0, 1.0])


@layouts
def test_axis_parallel_rays_on_a_grid_of_boxes_equal_brute_force(rng, layout):
    # Flat, axis-aligned leaves (a block of unit cubes): rays along +-x, y, z, a
    # third of them exactly in the cubes' face planes.
    import trimesh

    from sparsecast.surface.mesh import subdivide

    cubes = [trimesh.creation.box(extents=(1, 1, 1)).apply_translation((i, j, k))
             for i in range(3) for j in range(3) for k in range(2)]
    cube = trimesh.util.concatenate(cubes)
    mesh = subdivide(TriangleMesh(np.asarray(cube.vertices), np.asarray(cube.faces), "cubes"), 1)
    n = 300
    o, d = [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            p = rng.uniform(-0.6, 2.6, (n, 3))
            p[: n // 3, (axis + 1) % 3] = np.round(p[: n // 3, (axis + 1) % 3] * 2) / 2  # on face planes
            p[:, axis] = -5.0 * sign
            dd = np.zeros((n, 3))
            dd[:, axis] = sign
            o.append(p)
            d.append(dd)
    o, d = np.concatenate(o), np.concatenate(d)
    hits = raycast(build_bvh(mesh, layout=layout), o, d)
    with np.errstate(invalid="ignore"):  # the brute force's 0 * inf in face planes
        t_ref, _ = brute_force_hits(mesh.triangles, o, d)
    # A ray in a face plane of a box (also the outer ones) still enters it and hits
    # the perpendicular faces' edges there.
    np.testing.assert_array_equal(hits.hit, np.isfinite(t_ref))
    np.testing.assert_allclose(hits.t[hits.hit], t_ref[hits.hit], atol=1e-9)
    assert hits.hit.mean() > 0.5


@layouts
def test_grazing_rays_equal_brute_force(rng, layout):
    # Rays at a few degrees from a wavy sheet's plane: long, thin traversals through many boxes.
    g = np.linspace(-1, 1, 41)
    xx, yy = np.meshgrid(g, g)
    v = np.c_[xx.ravel(), yy.ravel(), 0.02 * np.sin(4 * xx.ravel()) * np.cos(3 * yy.ravel())]
    q = np.arange(40 * 41).reshape(40, 41)[:, :40].ravel()
    q = q[(q % 41) < 40]
    f = np.concatenate([np.c_[q, q + 1, q + 42], np.c_[q, q + 42, q + 41]])
    mesh = TriangleMesh(v, f, "sheet")
    n = 600
    ang = np.radians(rng.uniform(0.5, 6.0, n))
    az = rng.uniform(0, 2 * np.pi, n)
    d = np.c_[np.cos(ang) * np.cos(az), np.cos(ang) * np.sin(az), -np.sin(ang)]
    target = np.c_[rng.uniform(-0.8, 0.8, (n, 2)), np.zeros(n)]
    o = target - 2.0 * d
    _check_against_brute(mesh, o, d, layout=layout)


@layouts
def test_real_meshes_equal_brute_force(shared_file, rng, layout):
    from sparsecast.surface.mesh import z_up

    mesh = z_up(load_mesh(shared_file("stanford_bunny.ply")))
    pts = mesh.vertices[rng.integers(0, len(mesh.vertices), 300)]
    o, d = rays_at(pts, rng, mesh.diagonal, jitter=0.01 * mesh.diagonal)
    _, hits = _check_against_brute(mesh, o, d, layout=layout)
    assert hits.hit.mean() > 0.5


def test_wide_layout_is_watertight():
    # Rays through the vertices and edge midpoints of a closed mesh: a shared edge
    # or vertex belongs to every triangle around it, and one of them must report it.
    mesh = icosphere(3)
    e = mesh.faces[:, [0, 1]]
    targets = np.concatenate([mesh.vertices, 0.5 * (mesh.vertices[e[:, 0]] + mesh.vertices[e[:, 1]])])
    centre = np.zeros(3)
    d = targets - centre
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    # From outside towards the centre, and from the centre outwards.
    for o, dirs in ((targets + 2.0 * d, -d), (np.zeros_like(targets), d)):
        hits = raycast(build_bvh(mesh, layout="wide"), o, dirs)
        assert hits.hit.all(), f"{int((~hits.hit).sum())} rays through edges or vertices slipped through"


def test_layouts_share_the_build_and_agree(rng):
    mesh = icosphere(4)
    o, d = rays_at(mesh.vertices[rng.integers(0, len(mesh.vertices), 2000)], rng, 3.0, jitter=0.3)
    a = raycast(build_bvh(mesh, layout="binary"), o, d)
    b = raycast(build_bvh(mesh), o, d)
    np.testing.assert_array_equal(a.hit, b.hit)
    np.testing.assert_allclose(a.t[a.hit], b.t[a.hit], rtol=1e-9)
    np.testing.assert_array_equal(a.face, b.face)
    np.testing.assert_allclose(a.normals[a.hit], b.normals[a.hit], atol=1e-5)
    np.testing.assert_allclose(a.uv[a.hit], b.uv[a.hit], atol=1e-5)


def test_t_range_and_bad_rays():
    mesh = icosphere(1)
    index = build_bvh(mesh)
    hits = raycast(index, [[0, 0, -3]], [[0, 0, 1]], t_max=1.0)
    assert not hits.hit[0]
    hits = raycast(index, [[0, 0, -3]], [[0, 0, 1]], t_min=3.0)  # from inside: the far side
    assert hits.t[0] > 3.5
    with pytest.raises(ParameterError, match="directions"):
        raycast(index, [[0, 0, 0]], [[0, 0, 0]])
    with pytest.raises(ParameterError, match="origins"):
        raycast(index, np.zeros((2, 2)), np.zeros((2, 2)))
    with pytest.raises(ParameterError, match="NaN"):
        raycast(index, [[np.nan, 0, 0]], [[1, 0, 0]])
    with pytest.raises(ParameterError, match="index"):
        raycast(mesh, [[0, 0, 0]], [[1, 0, 0]])
    with pytest.raises(ParameterError, match="max_leaf"):
        build_bvh(mesh, max_leaf=0)
    with pytest.raises(ParameterError, match="layout"):
        build_bvh(mesh, layout="octree")
