"""Trilinear interpolation and gradients in index space (vertex-centred voxels)."""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def _axis(x, n):
    """Clamp coordinate ``x`` to ``[0, n-1]``; return (lower voxel, upper voxel, fraction)."""
    if x < 0.0:
        x = 0.0
    elif x > n - 1:
        x = float(n - 1)
    i0 = int(x)
    if i0 > n - 2:
        i0 = n - 2 if n >= 2 else 0
    i1 = i0 + 1 if n >= 2 else 0
    return i0, i1, x - i0


@njit(cache=True, inline="always")
def trilinear(data, x, y, z):
    """Trilinearly interpolated value at index-space point ``(x, y, z)``.

    ``data`` is ``(nz, ny, nx)``. Points outside the domain are clamped to it, so a
    lattice sample that rounding pushes an ulp outside the box reads the face value.
    Interpolation order (x, then y, then z) is fixed: every renderer calls this one
    function, so images agree bit for bit where they take the same samples.
    """
    nz, ny, nx = data.shape
    i0, i1, fx = _axis(x, nx)
    j0, j1, fy = _axis(y, ny)
    k0, k1, fz = _axis(z, nz)
    # Loads are converted to float first: unsigned differences would wrap.
    v000 = float(data[k0, j0, i0])
    v001 = float(data[k0, j0, i1])
    v010 = float(data[k0, j1, i0])
    v011 = float(data[k0, j1, i1])
    v100 = float(data[k1, j0, i0])
    v101 = float(data[k1, j0, i1])
    v110 = float(data[k1, j1, i0])
    v111 = float(data[k1, j1, i1])
    c00 = v000 + fx * (v001 - v000)
    c10 = v010 + fx * (v011 - v010)
    c01 = v100 + fx * (v101 - v100)
    c11 = v110 + fx * (v111 - v110)
    c0 = c00 + fy * (c10 - c00)
    c1 = c01 + fy * (c11 - c01)
    return c0 + fz * (c1 - c0)


@njit(cache=True)
def gradient(data, x, y, z):
    """Index-space gradient by central differences of trilinear samples (h = 1 voxel)."""
    gx = 0.5 * (trilinear(data, x + 1.0, y, z) - trilinear(data, x - 1.0, y, z))
    gy = 0.5 * (trilinear(data, x, y + 1.0, z) - trilinear(data, x, y - 1.0, z))
    gz = 0.5 * (trilinear(data, x, y, z + 1.0) - trilinear(data, x, y, z - 1.0))
    return gx, gy, gz
