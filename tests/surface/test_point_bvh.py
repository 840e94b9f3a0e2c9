"""The exact BVH over a point cloud's discs against brute force; clouds without normals."""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast.errors import ParameterError
from sparsecast.surface import PointCloud, build_bvh, raycast, render_surface
from sparsecast.surface.bvh import disc_boxes
from sparsecast import Camera

from .brute import brute_force_disc_hits, rays_at


def _random_cloud(rng, n):
    nrm = rng.normal(size=(n, 3))
    return PointCloud(rng.uniform(-1, 1, (n, 3)), nrm, rng.uniform(0.02, 0.15, n), "random discs")


@pytest.mark.parametrize("max_leaf", [1, 4])
def test_disc_bvh_equals_brute_force(rng, max_leaf):
    cloud = _random_cloud(rng, 400)
    index = build_bvh(cloud, max_leaf=max_leaf)
    o, d = rays_at(cloud.points[rng.integers(0, 400, 800)], rng, 4.0, jitter=0.08)
    hits = raycast(index, o, d)
    # The oracle sees the discs as the index stores them (float32).
    disc = index.discs[np.argsort(index.disc_point)].astype(np.float64)
    t_ref, k_ref = brute_force_disc_hits(disc[:, :3], disc[:, 3:6], disc[:, 6], o, d)
    np.testing.assert_array_equal(hits.hit, np.isfinite(t_ref))
    both = hits.hit
    assert 0.3 < both.mean() < 1.0  # hits and misses both exercised
    np.testing.assert_allclose(hits.t[both], t_ref[both], rtol=1e-6, atol=1e-6)
    assert int((hits.face[both] != k_ref[both]).sum()) <= 1  # a tie at equal t aside
    # The normal is the disc's (as stored), the hit point lies on its plane within its radius.
    k = hits.face[both]
    dots = np.abs(np.sum(hits.normals[both] * cloud.normals[k], -1))
    assert dots.min() > 0.9999
    off = hits.points[both] - cloud.points[k]
    assert np.abs(np.sum(off * cloud.normals[k], -1)).max() < 1e-5
    assert np.all(np.linalg.norm(off, axis=1) <= cloud.radii[k] * (1 + 1e-5))
    s = index.stats()
    assert s["discs"] == 400 and s["triangles"] == 0 and s["tiles"] == 0 and s["disc_leaves"] > 0
    assert np.all(hits.tile == -1)


def test_disc_boxes_are_tight():
    c = np.zeros((3, 3))
    n = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]) / np.array([[1.0], [1.0], [np.sqrt(2)]])
    lo, hi = disc_boxes(c, n, np.array([2.0, 2.0, 2.0]))
    np.testing.assert_allclose(hi[0], [2.0, 2.0, 0.0])  # flat along its normal
    np.testing.assert_allclose(hi[1], [0.0, 2.0, 2.0])
    np.testing.assert_allclose(hi[2], [np.sqrt(2), np.sqrt(2), 2.0])
    np.testing.assert_allclose(lo, -hi)


def test_a_disc_grid_is_a_closed_surface(rng):
    g = (np.arange(40) + 0.5) / 40
    xx, yy = np.meshgrid(g, g)
    pts = np.c_[xx.ravel(), yy.ravel(), np.zeros(xx.size)]
    cloud = PointCloud(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)))  # default radius from the spacing
    assert 1.0 / 40 <= cloud.radii[0] < 1.5 / 40
    index = build_bvh(cloud)
    target = np.c_[rng.uniform(0.05, 0.95, (400, 2)), np.zeros(400)]
    d = np.array([0.3, -0.2, -1.0]) / np.linalg.norm([0.3, -0.2, -1.0])
    hits = raycast(index, target - 2 * d, d)
    assert hits.hit.all()
    np.testing.assert_allclose(hits.points[:, 2], 0.0, atol=1e-6)
    img = render_surface(index, Camera.orbit(cloud, 0, 60), 32, 32)
    assert img.stats["hits"] > 0.3 * 32 * 32


def test_disc_bvh_needs_normals():
    with pytest.raises(ParameterError, match="normals"):
        build_bvh(PointCloud(np.random.default_rng(0).normal(size=(10, 3))))
