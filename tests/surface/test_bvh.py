"""The exact triangle BVH against brute force, and raycast's input checks."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparsecast.errors import ParameterError
from sparsecast.surface import build_bvh, raycast
from sparsecast.surface.mesh import TriangleMesh, icosphere

from .brute import brute_force_hits, rays_at


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


def test_sphere_rays_equal_brute_force(rng):
    mesh = icosphere(3)
    o, d = rays_at(mesh.vertices[rng.integers(0, len(mesh.vertices), 600)], rng, 3.0, jitter=0.4)
    index, hits = _check_against_brute(mesh, o, d)
    assert 0.3 < hits.hit.mean() < 1.0  # both hits and misses are exercised
    s = index.stats()
    assert s["triangles"] == mesh.n_triangles and s["tiles"] == 0 and s["nodes"] >= 2 * s["triangle_leaves"] - 1


@settings(max_examples=8)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 300), max_leaf=st.sampled_from([1, 4, 8]))
def test_random_soup_equals_brute_force(seed, n, max_leaf):
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-1, 1, (n, 1, 3))
    tris = centers + 0.3 * rng.normal(size=(n, 3, 3))
    mesh = TriangleMesh(tris.reshape(-1, 3), np.arange(3 * n).reshape(n, 3), "soup")
    o = rng.uniform(-2, 2, (200, 3))
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    _check_against_brute(mesh, o, d, max_leaf=max_leaf)


def test_axis_parallel_rays_hit_axis_aligned_faces():
    # Zero direction components must not turn box tests into NaN.
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], "tri")
    hits = raycast(build_bvh(mesh), [[0.25, 0.25, 1.0], [0.0, 0.0, 1.0]], [[0, 0, -1], [0, 0, -1]])
    np.testing.assert_allclose(hits.t, [1.0, 1.0])


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
