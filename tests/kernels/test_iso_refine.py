"""The isosurface bisection on each cell's cubic (`_refine_cubic`, trilinear volumes)
against the one that samples every step (`_refine_sampled`): the cubic is the
interpolated field along the ray, and the refined crossings agree to rounding for
brackets inside one cell, across cell faces, along axes and at the box faces."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from sparsecast.kernels.iso import ISO_STEPS, _refine_cubic, _refine_sampled, cell_cubic
from sparsecast.kernels.sample import corners, lerp8, trilinear
from sparsecast.kernels.sampler import Trilinear


@njit
def _both(flat, nx, ny, nz, rays, brackets, v):
    out = np.empty((rays.shape[0], 3))
    s = Trilinear()
    for i in range(rays.shape[0]):
        ox, oy, oz, dx, dy, dz = rays[i, 0], rays[i, 1], rays[i, 2], rays[i, 3], rays[i, 4], rays[i, 5]
        ta, tb = brackets[i, 0], brackets[i, 1]
        ga = trilinear(flat, nx, ny, nz, ox + ta * dx, oy + ta * dy, oz + ta * dz) - v
        gb = trilinear(flat, nx, ny, nz, ox + tb * dx, oy + tb * dy, oz + tb * dz) - v
        out[i, 0] = _refine_cubic(flat, nx, ny, nz, ox, oy, oz, dx, dy, dz, ta, tb, ga, gb, v)
        out[i, 1] = _refine_sampled(s, flat, nx, ny, nz, ox, oy, oz, dx, dy, dz, ta, tb, ga, gb, v)
        out[i, 2] = (ga >= 0.0) != (gb >= 0.0)  # a crossing to refine
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


def _check(out, brackets, share=0.99, atol=1e-9, min_crossing=0.1):
    crossing = out[:, 2] == 1.0
    assert crossing.sum() >= min_crossing * len(out)
    t_c, t_s = out[crossing, 0], out[crossing, 1]
    ta, tb = brackets[crossing, 0], brackets[crossing, 1]
    assert np.all((t_c >= ta) & (t_c <= tb))
    # Bisection decisions only part where the field is within rounding of v: then the
    # two final brackets both hold a crossing and lie within one bracket width.
    assert np.all(np.abs(t_c - t_s) <= (tb - ta) / 2 ** (ISO_STEPS - 1))
    # Elsewhere the two differ by the rounding of the field's values (float32 volumes
    # interpolate in float32, the cubic in float64).
    assert np.sum(np.isclose(t_c, t_s, rtol=0.0, atol=atol)) >= share * t_c.size


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize("step", [0.3, 1.0, 2.5])
def test_cubic_bisection_agrees_with_the_sampled_one(dtype, step):
    rng = np.random.default_rng(11)
    shape = (9, 7, 6)
    data = (rng.random(shape) * 200).astype(dtype)
    rays, brackets = _rays(rng, 3000, shape, step)
    out = _both(data.reshape(-1), shape[2], shape[1], shape[0], rays, brackets, 100.0)
    _check(out, brackets, atol=1e-5 if dtype == np.float32 else 1e-9)  # a tenth of the brackets cross v


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), thin=st.sampled_from([(1, 4, 5), (4, 1, 5), (4, 5, 1), (2, 2, 2)]))
def test_cubic_bisection_on_thin_volumes(seed, thin):
    # axes of one or two voxels: _axis's clamped cells
    rng = np.random.default_rng(seed)
    data = rng.random(thin).astype(np.float32)
    rays, brackets = _rays(rng, 256, thin, 1.0)
    out = _both(data.reshape(-1), thin[2], thin[1], thin[0], rays, brackets, 0.5)
    _check(out, brackets, share=0.95, atol=1e-5, min_crossing=0.0)  # few crossings on some seeds


@njit
def _cubic_vs_lerp(flat, nx, ny, nz, p, d, s):
    x, y, z = p
    v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz = corners(flat, nx, ny, nz, x, y, z)
    c0, c1, c2, c3 = cell_cubic(v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz, d[0], d[1], d[2])
    out = np.empty((s.size, 2))
    for i in range(s.size):
        out[i, 0] = c0 + s[i] * (c1 + s[i] * (c2 + s[i] * c3))
        out[i, 1] = lerp8(v000, v001, v010, v011, v100, v101, v110, v111,
                          fx + s[i] * d[0], fy + s[i] * d[1], fz + s[i] * d[2])
    return out, c0 == trilinear(flat, nx, ny, nz, x, y, z)


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), axis=st.sampled_from([-1, 0, 1, 2]))
def test_cell_cubic_is_the_trilinear_field_along_the_line(seed, axis):
    rng = np.random.default_rng(seed)
    data = rng.uniform(-50, 250, (3, 4, 5))
    p = rng.uniform([0.0, 0.0, 0.0], [3.999, 2.999, 1.999])
    d = rng.normal(size=3)
    if axis >= 0:
        d[[a for a in range(3) if a != axis]] = 0.0  # along one axis: the cubic's higher terms vanish
    d /= np.linalg.norm(d)
    out, exact_at_0 = _cubic_vs_lerp(data.reshape(-1), 5, 4, 3, p, d, rng.uniform(-1.0, 1.0, 50))
    assert exact_at_0
    np.testing.assert_allclose(out[:, 0], out[:, 1], rtol=0, atol=1e-9 * 300)
