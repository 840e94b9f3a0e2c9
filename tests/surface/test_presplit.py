"""Spatial splits before the build: the references cover their triangles, and the BVH
built over them finds brute force's hits in both layouts."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparsecast.bench.surface import slivers
from sparsecast.errors import ParameterError
from sparsecast.surface import PointCloud, build_bvh, raycast
from sparsecast.surface.bvh import LAYOUTS
from sparsecast.surface.mesh import TriangleMesh
from sparsecast.surface.presplit import MAX_REFS, presplit_refs

from .brute import brute_force_hits


def _soup(rng, n, spread=0.6):
    centers = rng.uniform(-1, 1, (n, 1, 3))
    return (centers + spread * rng.normal(size=(n, 3, 3))).astype(np.float32)


def _half_area(lo, hi):
    e = (hi - lo).astype(np.float64)
    return float((e[:, 0] * e[:, 1] + e[:, 1] * e[:, 2] + e[:, 2] * e[:, 0]).sum())


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 200), budget=st.sampled_from([0.3, 1.0, 3.0]))
def test_references_cover_their_triangles_within_their_boxes(seed, n, budget):
    rng = np.random.default_rng(seed)
    tris = _soup(rng, n)
    lo, hi, ids = presplit_refs(tris, budget)
    assert lo.dtype == hi.dtype == np.float32 and ids.dtype == np.int32
    # Every triangle keeps a reference, and the budget bounds the extra ones.
    counts = np.bincount(ids, minlength=n)
    assert counts.min() >= 1 and counts.max() <= MAX_REFS
    assert len(ids) <= n + int(budget * n)
    # Each box lies within its triangle's box, and is a box.
    assert (lo <= hi).all()
    assert (lo >= tris.min(axis=1)[ids]).all() and (hi <= tris.max(axis=1)[ids]).all()
    # Points all over each triangle (vertices, edges, inside) lie in a box of one of its
    # references: the parts cover the triangle.
    w = rng.dirichlet((1.0, 1.0, 1.0), 64)
    w = np.concatenate([w, np.eye(3), [[0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]]])
    pts = np.einsum("kv,tva->tka", w, tris.astype(np.float64))  # (n, k, 3)
    covered = np.zeros(pts.shape[:2], bool)
    for r in range(len(ids)):
        t = ids[r]
        covered[t] |= np.all((pts[t] >= lo[r]) & (pts[t] <= hi[r]), axis=1)
    assert covered.all()


def test_splits_shrink_the_boxes_of_long_thin_triangles():
    tris = slivers(500).triangles.astype(np.float32)
    blo, bhi, _ = presplit_refs(tris, 0.0)
    lo, hi, ids = presplit_refs(tris, 1.0)
    assert len(ids) > 1.9 * len(tris)  # the budget is spent: every sliver has a large box
    assert _half_area(lo, hi) < 0.75 * _half_area(blo, bhi)  # two parts of a diagonal: about half


def test_no_budget_is_one_box_a_triangle(rng):
    tris = _soup(rng, 50)
    lo, hi, ids = presplit_refs(tris, 0.0)
    assert np.array_equal(ids, np.arange(50))
    assert np.array_equal(lo, tris.min(axis=1)) and np.array_equal(hi, tris.max(axis=1))


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 300), splits=st.sampled_from([0.5, 1.0, 4.0]),
       layout=st.sampled_from(LAYOUTS))
def test_split_bvh_equals_brute_force(seed, n, splits, layout):
    rng = np.random.default_rng(seed)
    tris = _soup(rng, n, 0.5)
    mesh = TriangleMesh(tris.reshape(-1, 3), np.arange(3 * n).reshape(n, 3), "soup")
    o = rng.uniform(-2, 2, (300, 3))
    d = rng.normal(size=(300, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    index = build_bvh(mesh, splits=splits, layout=layout)
    hits = raycast(index, o, d)
    t_ref, f_ref = brute_force_hits(mesh.triangles, o, d)
    np.testing.assert_array_equal(hits.hit, np.isfinite(t_ref))
    np.testing.assert_allclose(hits.t[hits.hit], t_ref[hits.hit], rtol=1e-5, atol=1e-5)
    assert index.stats()["references"] >= n and index.stats()["splits"] == splits


@pytest.mark.parametrize("layout", LAYOUTS)
def test_split_bvh_on_slivers_with_axis_parallel_rays(rng, layout):
    # Rays along the axes, some of them in the grid planes the splits cut at (the
    # mesh box's halves and quarters), hit what brute force hits.
    mesh = slivers(2000, seed=3)
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    grid = lo + (hi - lo) * np.array([0.25, 0.5, 0.75])[:, None]
    rays_o, rays_d = [], []
    for a in range(3):
        for _ in range(200):
            p = rng.uniform(lo, hi)
            b, c = (a + 1) % 3, (a + 2) % 3
            if rng.random() < 0.5:
                p[b] = grid[rng.integers(3), b]
            p[a] = lo[a] - 1.0
            d = np.zeros(3)
            d[a] = 1.0
            rays_o.append(p)
            rays_d.append(d)
    o, d = np.array(rays_o), np.array(rays_d)
    split = raycast(build_bvh(mesh, splits=2.0, layout=layout), o, d)
    t_ref, _ = brute_force_hits(mesh.triangles, o, d)
    np.testing.assert_array_equal(split.hit, np.isfinite(t_ref))
    np.testing.assert_allclose(split.t[split.hit], t_ref[split.hit], rtol=1e-5, atol=1e-5)
    assert split.hit.mean() > 0.2


def test_bad_splits_name_the_parameter(rng):
    mesh = TriangleMesh(_soup(rng, 4).reshape(-1, 3), np.arange(12).reshape(4, 3), "soup")
    for bad in (-0.5, 5.0, float("nan"), "many", True):
        with pytest.raises(ParameterError, match="splits"):
            build_bvh(mesh, splits=bad)
    cloud = PointCloud(rng.normal(size=(20, 3)), normals=np.tile([0.0, 0.0, 1.0], (20, 1)), radii=0.1)
    with pytest.raises(ParameterError, match="splits: spatial splits cut triangles"):
        build_bvh(cloud, splits=1.0)
