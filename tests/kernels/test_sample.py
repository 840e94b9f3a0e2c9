"""The central-difference gradient: the interior fast path (bilinear lines through the
centre cell) against six clamped trilinear samples, exact on linear fields, and the same
floats whether its voxels are read one by one or as runs."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from sparsecast.kernels.sample import gradient, gradient_clamped


@njit
def _both(flat, nx, ny, nz, pts):
    out = np.empty((pts.shape[0], 6))
    for i in range(pts.shape[0]):
        a = gradient(flat, nx, ny, nz, pts[i, 0], pts[i, 1], pts[i, 2])
        b = gradient_clamped(flat, nx, ny, nz, pts[i, 0], pts[i, 1], pts[i, 2])
        out[i, :3] = a
        out[i, 3:] = b
    return out


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
def test_fast_gradient_equals_six_samples(dtype):
    rng = np.random.default_rng(3)
    nz, ny, nx = 12, 9, 7
    data = (rng.random((nz, ny, nx)) * 250).astype(dtype)
    # interior points, points within a voxel of a face (the clamped path) and on faces
    pts = rng.uniform(0.0, [nx - 1.0, ny - 1.0, nz - 1.0], (4000, 3))
    pts[:500, 0] = rng.choice([0.0, 0.3, 0.999, nx - 2.0, nx - 1.5, nx - 1.0], 500)
    pts[500:1000, 2] = rng.choice([0.0, 1.0, 1.0 - 1e-12, nz - 2.0, nz - 1.0], 500)
    out = _both(data.reshape(-1), nx, ny, nz, pts)
    fast, six = out[:, :3], out[:, 3:]
    # float32 voxels: differences of two float32 corners round in float32 either way
    rtol = 1e-6 if dtype == np.float32 else 1e-12
    np.testing.assert_allclose(fast, six, rtol=0, atol=rtol * 250)
    interior = np.all((pts >= 1.0) & (pts < np.array([nx, ny, nz]) - 2.0), axis=1)
    assert interior.sum() > 1000  # the fast path was taken, not only the fallback
    assert np.array_equal(fast[~interior], six[~interior])  # near faces: the clamped samples themselves


def test_gradient_of_a_linear_field_is_its_slope():
    nz, ny, nx = 10, 11, 12
    z, y, x = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    data = (3.0 * x - 2.0 * y + 0.5 * z + 7.0).astype(np.float64)
    pts = np.random.default_rng(1).uniform(1.0, [nx - 2.5, ny - 2.5, nz - 2.5], (500, 3))
    out = _both(data.reshape(-1), nx, ny, nz, pts)
    np.testing.assert_allclose(out[:, :3], np.tile([3.0, -2.0, 0.5], (500, 1)), atol=1e-12)


@njit
def _gradients(flat, nx, ny, nz, pts):
    out = np.empty((pts.shape[0], 3))
    for i in range(pts.shape[0]):
        out[i] = gradient(flat, nx, ny, nz, pts[i, 0], pts[i, 1], pts[i, 2])
    return out


@pytest.mark.parametrize("dtype", [np.uint8, np.int8, np.uint16, np.int16, np.float32, np.float64])
def test_run_loads_give_the_item_reads_floats(dtype):
    # A C array takes the interior gradient's voxels as runs along x (vectorize.load_run,
    # all but float64); a strided view of the same values item by item: same floats
    rng = np.random.default_rng(5)
    nz, ny, nx = 8, 6, 7
    data = (rng.random((nz, ny, nx)) * 120 - (60 if np.dtype(dtype).kind in "if" else 0)).astype(dtype)
    flat = data.reshape(-1)
    strided = np.empty(2 * flat.size, dtype)[::2]
    strided[:] = flat
    pts = rng.uniform(0.0, [nx - 1.0, ny - 1.0, nz - 1.0], (3000, 3))
    runs = _gradients(flat, nx, ny, nz, pts)
    items = _gradients(strided, nx, ny, nz, pts)
    interior = np.all((pts >= 1.0) & (pts < np.array([nx, ny, nz]) - 2.0), axis=1)
    assert interior.sum() > 300
    assert np.array_equal(runs, items)
    # and what the gradient is: the slope of the trilinear field, here against six samples
    np.testing.assert_allclose(runs, _both(flat, nx, ny, nz, pts)[:, 3:], rtol=0, atol=1e-4 * 120)
