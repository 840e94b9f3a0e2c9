"""The isosurface bisection that reads a cell's corners once (`_refine_cells`, trilinear
dense volumes) against the one that samples every step (`_refine_sampled`): the same
float for brackets inside one cell, across cell faces, along axes and at the box faces."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from sparsecast.kernels.iso import _refine_cells, _refine_sampled
from sparsecast.kernels.sample import trilinear
from sparsecast.kernels.sampler import Trilinear


@njit
def _both(flat, nx, ny, nz, rays, brackets, v):
    out = np.empty((rays.shape[0], 2))
    s = Trilinear()
    for i in range(rays.shape[0]):
        ox, oy, oz, dx, dy, dz = rays[i, 0], rays[i, 1], rays[i, 2], rays[i, 3], rays[i, 4], rays[i, 5]
        ta, tb = brackets[i, 0], brackets[i, 1]
        ga = trilinear(flat, nx, ny, nz, ox + ta * dx, oy + ta * dy, oz + ta * dz) - v
        gb = trilinear(flat, nx, ny, nz, ox + tb * dx, oy + tb * dy, oz + tb * dz) - v
        out[i, 0] = _refine_cells(flat, nx, ny, nz, ox, oy, oz, dx, dy, dz, ta, tb, ga, gb, v)
        out[i, 1] = _refine_sampled(s, flat, nx, ny, nz, ox, oy, oz, dx, dy, dz, ta, tb, ga, gb, v)
    return out


def _rays(rng, n, shape, step):
    nz, ny, nx = shape
    hi = np.array([nx - 1.0, ny - 1.0, nz - 1.0])
    a = rng.uniform(0.0, hi, (n, 3))
    d = rng.normal(size=(n, 3))
    d[: n // 4, 1:] = 0.0  # along x
    d[n // 4: n // 2, :2] = 0.0  # along z
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    b = np.clip(a + step * d, 0.0, hi)  # brackets may end on a box face
    a[: n // 8] = np.round(a[: n // 8])  # brackets starting on lattice points
    return np.hstack([a, b - a]), np.tile([0.0, 1.0], (n, 1))


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize("step", [0.3, 1.0, 2.5])
def test_cell_reuse_gives_the_sampled_bisection_bit_for_bit(dtype, step):
    rng = np.random.default_rng(11)
    shape = (9, 7, 6)
    data = (rng.random(shape) * 200).astype(dtype)
    rays, brackets = _rays(rng, 3000, shape, step)
    out = _both(data.reshape(-1), shape[2], shape[1], shape[0], rays, brackets, 100.0)
    np.testing.assert_array_equal(out[:, 0], out[:, 1])
    # the brackets did cross the isovalue often enough to exercise the bisection
    t = out[:, 0]
    assert ((t > 0.0) & (t < 1.0)).sum() > 300


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), thin=st.sampled_from([(1, 4, 5), (4, 1, 5), (4, 5, 1), (2, 2, 2)]))
def test_cell_reuse_on_thin_volumes(seed, thin):
    # axes of one or two voxels: _axis's clamped cells
    rng = np.random.default_rng(seed)
    data = rng.random(thin).astype(np.float32)
    rays, brackets = _rays(rng, 64, thin, 1.0)
    out = _both(data.reshape(-1), thin[2], thin[1], thin[0], rays, brackets, 0.5)
    np.testing.assert_array_equal(out[:, 0], out[:, 1])
