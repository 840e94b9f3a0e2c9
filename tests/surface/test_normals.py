"""Normals estimated by PCA over nearest neighbours match analytic normals; orientation."""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast.errors import ParameterError
from sparsecast.surface.normals import estimate_normals


def _sphere(rng, n, radius=2.0, center=(1.0, -1.0, 0.5)):
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return np.asarray(center) + radius * u, u


def test_sphere_normals_match_and_point_outwards(rng):
    pts, truth = _sphere(rng, 3000)
    n = estimate_normals(pts, k=12)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    dot = np.sum(n * truth, axis=1)
    assert dot.min() > 0.99  # right line and outward sign (away from the centroid)


def test_noisy_tilted_plane(rng):
    normal = np.array([1.0, 2.0, 2.0]) / 3.0
    a = np.cross(normal, [0.0, 0.0, 1.0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    uv = rng.uniform(-1, 1, (2000, 2))
    pts = uv[:, :1] * a + uv[:, 1:] * b + 1e-3 * rng.normal(size=(2000, 1)) * normal
    n = estimate_normals(pts)
    assert np.abs(n @ normal).min() > 0.99
    # Towards a viewpoint on the negative side: every normal faces it.
    view = -5.0 * normal
    n = estimate_normals(pts, towards=view)
    assert np.all(np.sum(n * (view - pts), axis=1) >= 0) and (n @ normal).max() < -0.99


def test_bad_input():
    with pytest.raises(ParameterError, match="at least 3"):
        estimate_normals(np.zeros((2, 3)))
    with pytest.raises(ParameterError, match="k"):
        estimate_normals(np.random.default_rng(0).normal(size=(10, 3)), k=1)
    with pytest.raises(ParameterError, match="shape"):
        estimate_normals(np.zeros((10, 2)))
    with pytest.raises(ParameterError, match="towards"):
        estimate_normals(np.random.default_rng(0).normal(size=(10, 3)), towards=(0, 0))
