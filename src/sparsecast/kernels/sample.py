"""Trilinear interpolation and gradients in index space (vertex-centred voxels)."""

from __future__ import annotations

from numba import njit

from .borrow import NO_REFCOUNT


@njit(cache=True, inline="always")
def _axis(x, n):
    """Cell of coordinate ``x`` on an axis of ``n`` voxels: (lower voxel, upper voxel, fraction).

    Only the integer cell index is clamped (to ``[0, max(n-2, 0)]``), which keeps
    every read inside the array; the fraction is not, so a lattice point that
    rounding puts an ulp outside the box extrapolates by an ulp. Clamping the
    float coordinate as well cost ~12 % of the marching time. An axis of one
    voxel gives ``(0, 0, x)``; its fraction multiplies a zero difference.
    """
    i0 = min(max(int(x), 0), max(n - 2, 0))
    return i0, i0 + min(n - 1, 1), x - i0


@njit(cache=True, inline="always")
def clamp_point(x, y, z, nx, ny, nz):
    """Clamp an index-space point to the volume box ``[0, n-1]^3``."""
    return (
        min(max(x, 0.0), nx - 1.0),
        min(max(y, 0.0), ny - 1.0),
        min(max(z, 0.0), nz - 1.0),
    )


@njit(cache=True, inline="always")
def trilinear(flat, nx, ny, nz, x, y, z):
    """Trilinearly interpolated value at index-space point ``(x, y, z)``.

    ``flat`` is the C-ordered ``(nz, ny, nx)`` voxel array viewed as 1-D
    (``data.reshape(-1)``): computing the eight addresses from two offsets per
    axis is cheaper than eight 3-D index computations (about 1.3x faster
    marching). Callers pass points inside the box (lattice samples are, up to
    rounding; see :func:`_axis`); :func:`clamp_point` handles others.
    Interpolation order (x, then y, then z) is fixed: every renderer calls this
    one function, so images agree bit for bit where they take the same samples.
    """
    i0, i1, fx = _axis(x, nx)
    j0, j1, fy = _axis(y, ny)
    k0, k1, fz = _axis(z, nz)
    row0 = k0 * ny
    row1 = k1 * ny
    a00 = (row0 + j0) * nx
    a01 = (row0 + j1) * nx
    a10 = (row1 + j0) * nx
    a11 = (row1 + j1) * nx
    # Loads are converted to float first: unsigned differences would wrap.
    v000 = float(flat[a00 + i0])
    v001 = float(flat[a00 + i1])
    v010 = float(flat[a01 + i0])
    v011 = float(flat[a01 + i1])
    v100 = float(flat[a10 + i0])
    v101 = float(flat[a10 + i1])
    v110 = float(flat[a11 + i0])
    v111 = float(flat[a11 + i1])
    return lerp8(v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz)


@njit(cache=True, inline="always")
def lerp8(v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz):
    """Trilinear interpolation of a cell's corner values (``v_kji``), x then y then z.

    The one interpolation every voxel layout uses (dense here, bricked in
    :mod:`.bricked`), so the layouts return the same float for the same corners.
    """
    c00 = v000 + fx * (v001 - v000)
    c10 = v010 + fx * (v011 - v010)
    c01 = v100 + fx * (v101 - v100)
    c11 = v110 + fx * (v111 - v110)
    c0 = c00 + fy * (c10 - c00)
    c1 = c01 + fy * (c11 - c01)
    return c0 + fz * (c1 - c0)


@njit(cache=True, **NO_REFCOUNT)
def gradient(flat, nx, ny, nz, x, y, z):
    """Index-space gradient by central differences of trilinear samples (h = 1 voxel).

    Neighbours outside the box are clamped to it (one-sided differences at faces).
    """
    x0, y0, z0 = clamp_point(x - 1.0, y - 1.0, z - 1.0, nx, ny, nz)
    x1, y1, z1 = clamp_point(x + 1.0, y + 1.0, z + 1.0, nx, ny, nz)
    gx = 0.5 * (trilinear(flat, nx, ny, nz, x1, y, z) - trilinear(flat, nx, ny, nz, x0, y, z))
    gy = 0.5 * (trilinear(flat, nx, ny, nz, x, y1, z) - trilinear(flat, nx, ny, nz, x, y0, z))
    gz = 0.5 * (trilinear(flat, nx, ny, nz, x, y, z1) - trilinear(flat, nx, ny, nz, x, y, z0))
    return gx, gy, gz


@njit(cache=True, inline="always")
def corners(flat, nx, ny, nz, x, y, z):
    """The eight voxel values of the trilinear cell of ``(x, y, z)`` and its fractions.

    Returns ``(v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz)`` with
    ``v_kji`` the corner ``k`` steps along z, ``j`` along y and ``i`` along x from the
    cell's lower corner, picked exactly as :func:`trilinear` picks them (same cell, same
    unclamped fractions). Label volumes interpolate per-label weights of these corners
    instead of their values (:mod:`.sampler`, ``SmoothLabels``).
    """
    i0, i1, fx = _axis(x, nx)
    j0, j1, fy = _axis(y, ny)
    k0, k1, fz = _axis(z, nz)
    a00 = (k0 * ny + j0) * nx
    a01 = (k0 * ny + j1) * nx
    a10 = (k1 * ny + j0) * nx
    a11 = (k1 * ny + j1) * nx
    return (
        float(flat[a00 + i0]), float(flat[a00 + i1]), float(flat[a01 + i0]), float(flat[a01 + i1]),
        float(flat[a10 + i0]), float(flat[a10 + i1]), float(flat[a11 + i0]), float(flat[a11 + i1]),
        fx, fy, fz,
    )
