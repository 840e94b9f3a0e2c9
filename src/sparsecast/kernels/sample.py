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


@njit(cache=True, inline="always")
def _bilerp(a, b, c, d, u, v):
    """Bilinear interpolation: ``a``, ``b`` along ``u`` at ``v = 0``, ``c``, ``d`` at ``v = 1``."""
    ab = a + u * (b - a)
    cd = c + u * (d - c)
    return ab + v * (cd - ab)


@njit(cache=True, **NO_REFCOUNT)
def gradient(flat, nx, ny, nz, x, y, z):
    """Index-space gradient by central differences of trilinear samples (h = 1 voxel).

    Neighbours outside the box are clamped to it (one-sided differences at faces).

    Away from the faces (the cell and its six neighbours inside the volume) the six
    neighbours are one cell over with the centre's fractions, so each axis takes a
    line of four bilinear interpolations across it, and the lines share the centre
    cell's corners: 32 voxels read from one base address instead of six trilinear
    samples (48 voxels, six cell look-ups). The value equals the six samples' up to
    rounding (the fractions of ``x + 1`` and ``x`` may differ by an ulp); every
    renderer calls this one function, so images still agree bit for bit.
    """
    i0 = int(x)
    j0 = int(y)
    k0 = int(z)
    if 1 <= i0 and i0 + 2 < nx and 1 <= j0 and j0 + 2 < ny and 1 <= k0 and k0 + 2 < nz:
        return interior_gradient(flat, nx, nx * ny, (k0 * ny + j0) * nx + i0, x - i0, y - j0, z - k0)
    return gradient_clamped(flat, nx, ny, nz, x, y, z)


@njit(cache=True, inline="always")
def interior_gradient(flat, sy, sz, b, fx, fy, fz):
    """:func:`gradient` away from the faces: ``b`` is the address of the cell's lower
    corner, ``sy = nx`` and ``sz = nx * ny`` the strides of y and z, ``(fx, fy, fz)`` the
    fractions in the cell. Reads voxels ``b - sy - sz - 1 .. b + 2 (1 + sy + sz)``; the
    caller makes sure they are inside the volume. Shared with the packets' shading
    (:mod:`.packet`), so both take the same floats."""
    # the centre cell: c_kji, corner k along z, j along y, i along x
    c000 = float(flat[b])
    c001 = float(flat[b + 1])
    c010 = float(flat[b + sy])
    c011 = float(flat[b + sy + 1])
    c100 = float(flat[b + sz])
    c101 = float(flat[b + sz + 1])
    c110 = float(flat[b + sz + sy])
    c111 = float(flat[b + sz + sy + 1])
    # x: columns i0 - 1 .. i0 + 2, each bilinear in (y, z)
    xm = _bilerp(float(flat[b - 1]), float(flat[b + sy - 1]), float(flat[b + sz - 1]),
                 float(flat[b + sz + sy - 1]), fy, fz)
    x0 = _bilerp(c000, c010, c100, c110, fy, fz)
    x1 = _bilerp(c001, c011, c101, c111, fy, fz)
    xp = _bilerp(float(flat[b + 2]), float(flat[b + sy + 2]), float(flat[b + sz + 2]),
                 float(flat[b + sz + sy + 2]), fy, fz)
    gx = 0.5 * ((x1 + fx * (xp - x1)) - (xm + fx * (x0 - xm)))
    # y: rows j0 - 1 .. j0 + 2, each bilinear in (x, z)
    ym = _bilerp(float(flat[b - sy]), float(flat[b - sy + 1]), float(flat[b + sz - sy]),
                 float(flat[b + sz - sy + 1]), fx, fz)
    y0 = _bilerp(c000, c001, c100, c101, fx, fz)
    y1 = _bilerp(c010, c011, c110, c111, fx, fz)
    yp = _bilerp(float(flat[b + 2 * sy]), float(flat[b + 2 * sy + 1]), float(flat[b + sz + 2 * sy]),
                 float(flat[b + sz + 2 * sy + 1]), fx, fz)
    gy = 0.5 * ((y1 + fy * (yp - y1)) - (ym + fy * (y0 - ym)))
    # z: slices k0 - 1 .. k0 + 2, each bilinear in (x, y)
    zm = _bilerp(float(flat[b - sz]), float(flat[b - sz + 1]), float(flat[b - sz + sy]),
                 float(flat[b - sz + sy + 1]), fx, fy)
    z0 = _bilerp(c000, c001, c010, c011, fx, fy)
    z1 = _bilerp(c100, c101, c110, c111, fx, fy)
    zp = _bilerp(float(flat[b + 2 * sz]), float(flat[b + 2 * sz + 1]), float(flat[b + 2 * sz + sy]),
                 float(flat[b + 2 * sz + sy + 1]), fx, fy)
    gz = 0.5 * ((z1 + fz * (zp - z1)) - (zm + fz * (z0 - zm)))
    return gx, gy, gz


@njit(cache=True, **NO_REFCOUNT)
def gradient_clamped(flat, nx, ny, nz, x, y, z):
    """:func:`gradient` by six trilinear samples, clamped to the box (any point)."""
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
