"""Trilinear interpolation and gradients in index space (vertex-centred voxels)."""

from __future__ import annotations

from numba import njit
from numba.extending import overload

from .borrow import NO_REFCOUNT
from .vectorize import load_run, load_window, run_loadable


@njit(cache=True)
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


@njit(cache=True)
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
    v000, v001, v010, v011, v100, v101, v110, v111 = cell_values(flat, nx, ny, i0, i1, j0, j1, k0, k1)
    return lerp8(v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz)


@njit(cache=True)
def cell_of(x, y, z, nx, ny, nz):
    """The trilinear cell of ``(x, y, z)`` as :func:`trilinear` picks it.

    Returns ``(i0, i1, fx, j0, j1, fy, k0, k1, fz)``: per axis the lower and upper
    voxel and the (unclamped) fraction, see :func:`_axis`.
    """
    i0, i1, fx = _axis(x, nx)
    j0, j1, fy = _axis(y, ny)
    k0, k1, fz = _axis(z, nz)
    return i0, i1, fx, j0, j1, fy, k0, k1, fz


@njit(cache=True, inline="always")
def cell_values(flat, nx, ny, i0, i1, j0, j1, k0, k1):
    """The eight corner values ``v_kji`` of a cell of :func:`cell_of`, as float64.

    ``trilinear(...) == lerp8(*cell_values(...), fx, fy, fz)`` bit for bit: a
    caller that samples one cell several times can read its corners once.
    """
    row0 = k0 * ny
    row1 = k1 * ny
    a00 = (row0 + j0) * nx
    a01 = (row0 + j1) * nx
    a10 = (row1 + j0) * nx
    a11 = (row1 + j1) * nx
    # Loads are converted to float first: unsigned differences would wrap.
    return (
        float(flat[a00 + i0]), float(flat[a00 + i1]), float(flat[a01 + i0]), float(flat[a01 + i1]),
        float(flat[a10 + i0]), float(flat[a10 + i1]), float(flat[a11 + i0]), float(flat[a11 + i1]),
    )


def trilinear_pairs(flat, nx, ny, nz, x, y, z):  # pragma: no cover - replaced by an overload in jitted code
    """:func:`trilinear` for volumes of at least :func:`pairs_min_nx` voxels along x,
    reading each pair of corners along x with one load where the dtype allows
    (:func:`.vectorize.run_loadable`): 4 loads instead of 8, the same values, so the same
    float. The caller makes sure ``nx >= pairs_min_nx(flat)``: the packets' lane loop
    (:func:`.packet.sample_packet`) tests it once outside the loop; the test inside the
    lane loop made it 1.2-1.5x slower than item reads.

    8-bit pairs are read from 32-bit words: x86 gathers 32- and 64-bit items only, so a
    16-bit read in a vectorised lane loop is a scalar load and an insert per lane. The
    word is the row's four voxels from ``s = min(i0, nx - 4)`` (inside the row, hence
    ``nx >= 4``), the pair picked by a shift of ``i0 - s`` voxels (nonzero in the row's
    last two cells only). Measured against 16-bit reads (alternating processes, one
    thread, 512², Intel Xeon with AVX-512, 2026-12-06): naive isosurface frames, whose
    packets read values only, 1.19-1.59x less CPU (tooth, mni152); dense-TF DVR frames
    within noise (0.93-1.06x; their table reads were gathers already).
    """
    raise NotImplementedError("trilinear_pairs is only callable from jitted code")


def pairs_min_nx(flat):  # pragma: no cover - replaced by an overload in jitted code
    """The fewest voxels along x for which :func:`trilinear_pairs` may read voxels of
    Numba type ``flat``: 4 for 8-bit data (its words of four voxels), else 2. A constant
    in jitted code, so a test of ``nx`` against it costs one comparison."""
    raise NotImplementedError("pairs_min_nx is only callable from jitted code")


def _byte_words(flat) -> bool:
    # 8-bit voxels, whose pairs trilinear_pairs reads from words of four
    return run_loadable(flat, 4) and flat.dtype.bitwidth == 8


@overload(pairs_min_nx, inline="always")
def _pairs_min_nx(flat):
    least = 4 if _byte_words(flat) else 2
    return lambda flat: least


@overload(trilinear_pairs, inline="always")
def _trilinear_pairs(flat, nx, ny, nz, x, y, z):
    if _byte_words(flat):
        return _trilinear_word_loads
    return _trilinear_pair_loads if run_loadable(flat, 2) else _trilinear_item_loads


def _trilinear_word_loads(flat, nx, ny, nz, x, y, z):
    i0, _, fx = _axis(x, nx)
    j0, _, fy = _axis(y, ny)
    k0, _, fz = _axis(z, nz)
    sy = nx if ny > 1 else 0  # as in _trilinear_pair_loads
    sz = nx * ny if nz > 1 else 0
    s = min(i0, nx - 4)
    skip = i0 - s
    a = (k0 * ny + j0) * nx + s
    v000, v001 = load_window(flat, a, 4, skip, 2)
    v010, v011 = load_window(flat, a + sy, 4, skip, 2)
    v100, v101 = load_window(flat, a + sz, 4, skip, 2)
    v110, v111 = load_window(flat, a + sz + sy, 4, skip, 2)
    return lerp8(v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz)


def _trilinear_pair_loads(flat, nx, ny, nz, x, y, z):
    i0, _, fx = _axis(x, nx)
    j0, _, fy = _axis(y, ny)
    k0, _, fz = _axis(z, nz)
    # The cell's upper voxels are one row / one slice on (none on an axis of one
    # voxel, see _axis): the four rows' addresses from one product, where four
    # products per lane (64-bit vector multiplies, slow) were computed before.
    sy = nx if ny > 1 else 0
    sz = nx * ny if nz > 1 else 0
    a = (k0 * ny + j0) * nx + i0
    v000, v001 = load_run(flat, a, 2)
    v010, v011 = load_run(flat, a + sy, 2)
    v100, v101 = load_run(flat, a + sz, 2)
    v110, v111 = load_run(flat, a + sz + sy, 2)
    return lerp8(v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz)


def _trilinear_item_loads(flat, nx, ny, nz, x, y, z):
    return trilinear(flat, nx, ny, nz, x, y, z)


@njit(cache=True)
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


@njit(cache=True)
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


def interior_gradient(flat, sy, sz, b, fx, fy, fz):  # pragma: no cover - replaced by an overload in jitted code
    """:func:`gradient` away from the faces: ``b`` is the address of the cell's lower
    corner, ``sy = nx`` and ``sz = nx * ny`` the strides of y and z, ``(fx, fy, fz)`` the
    fractions in the cell. Reads voxels ``b - sy - sz - 1 .. b + 2 (1 + sy + sz)``; the
    caller makes sure they are inside the volume. Shared with the packets' shading
    (:mod:`.packet`), so both take the same floats.

    The 32 voxels are the centre cell's 8 and, per axis, the 4 + 4 one voxel beyond it on
    either side. Where they allow it (:func:`.vectorize.run_loadable`) they are read as
    runs along x, one load per run: the four x-lines of four voxels (``i0 - 1 .. i0 + 2``,
    the centre cell's corners among them) and eight pairs ``(i0, i0 + 1)`` for y and z,
    12 loads instead of 32 (8- and 16-bit data; float32 in pairs, 16). Values and
    arithmetic are the same either way, so the gradient is the same float. For 8-bit
    data the pairs are read as 32-bit words (:func:`_pair`), so that all 12 loads are
    gathers in the packets' lane loops: dense-TF shaded frames of the naive marcher
    1.09-1.18x less CPU (tooth, mni152; 4 alternating pairs of processes, 512²,
    2026-12-06, Intel Xeon with AVX-512), images identical.
    """
    raise NotImplementedError("interior_gradient is only callable from jitted code")


@overload(interior_gradient, inline="always")
def _interior_gradient(flat, sy, sz, b, fx, fy, fz):
    return _interior_gradient_runs if run_loadable(flat, 2) else _interior_gradient_items


def _interior_gradient_runs(flat, sy, sz, b, fx, fy, fz):
    # x-lines i0 - 1 .. i0 + 2 at (j0, k0), (j0 + 1, k0), (j0, k0 + 1), (j0 + 1, k0 + 1)
    m00, c000, c001, p00 = _x_line(flat, b - 1)
    m01, c010, c011, p01 = _x_line(flat, b + sy - 1)
    m10, c100, c101, p10 = _x_line(flat, b + sz - 1)
    m11, c110, c111, p11 = _x_line(flat, b + sz + sy - 1)
    return _central_differences(
        (c000, c001, c010, c011, c100, c101, c110, c111), (m00, m01, m10, m11), (p00, p01, p10, p11),
        _pair(flat, b - sy) + _pair(flat, b + sz - sy),
        _pair(flat, b + 2 * sy) + _pair(flat, b + sz + 2 * sy),
        _pair(flat, b - sz) + _pair(flat, b - sz + sy),
        _pair(flat, b + 2 * sz) + _pair(flat, b + 2 * sz + sy),
        fx, fy, fz,
    )


def _pair(flat, a):  # pragma: no cover - replaced by an overload in jitted code
    """Voxels ``a, a + 1`` of a row along x, from one load. Bytes are read as the middle
    of the four ``a - 1 .. a + 2`` (the interior path's x-lines span the same columns, so
    they lie inside the volume): a 32-bit load, which LLVM gathers in the packets' lane
    loops (:mod:`.packet`), where a 16-bit one is a scalar load and an insert per lane
    (x86 has no 16-bit gather). Shaded dense-TF frames of a uint8 volume: see
    :func:`interior_gradient`."""
    raise NotImplementedError("only callable from jitted code")


@overload(_pair, jit_options=NO_REFCOUNT)
def _pair_by_type(flat, a):
    return _pair_of_four if _byte_words(flat) else _pair_of_two


def _pair_of_four(flat, a):
    _, v0, v1, _ = load_run(flat, a - 1, 4)
    return v0, v1


def _pair_of_two(flat, a):
    return load_run(flat, a, 2)


def _x_line(flat, a):  # pragma: no cover - replaced by an overload in jitted code
    """Voxels ``a .. a + 3`` of a row along x: one load (8- and 16-bit voxels) or two."""
    raise NotImplementedError("only callable from jitted code")


@overload(_x_line, jit_options=NO_REFCOUNT)
def _x_line_by_type(flat, a):
    return _x_line_one_load if run_loadable(flat, 4) else _x_line_two_loads


def _x_line_one_load(flat, a):
    return load_run(flat, a, 4)


def _x_line_two_loads(flat, a):
    return load_run(flat, a, 2) + load_run(flat, a + 2, 2)


def _interior_gradient_items(flat, sy, sz, b, fx, fy, fz):
    # any dtype: one read per voxel
    return _central_differences(
        (float(flat[b]), float(flat[b + 1]), float(flat[b + sy]), float(flat[b + sy + 1]),
         float(flat[b + sz]), float(flat[b + sz + 1]), float(flat[b + sz + sy]), float(flat[b + sz + sy + 1])),
        (float(flat[b - 1]), float(flat[b + sy - 1]), float(flat[b + sz - 1]), float(flat[b + sz + sy - 1])),
        (float(flat[b + 2]), float(flat[b + sy + 2]), float(flat[b + sz + 2]), float(flat[b + sz + sy + 2])),
        (float(flat[b - sy]), float(flat[b - sy + 1]), float(flat[b + sz - sy]), float(flat[b + sz - sy + 1])),
        (float(flat[b + 2 * sy]), float(flat[b + 2 * sy + 1]), float(flat[b + sz + 2 * sy]),
         float(flat[b + sz + 2 * sy + 1])),
        (float(flat[b - sz]), float(flat[b - sz + 1]), float(flat[b - sz + sy]), float(flat[b - sz + sy + 1])),
        (float(flat[b + 2 * sz]), float(flat[b + 2 * sz + 1]), float(flat[b + 2 * sz + sy]),
         float(flat[b + 2 * sz + sy + 1])),
        fx, fy, fz,
    )


@njit(cache=True, inline="always")
def _central_differences(c, xm, xp, ym, yp, zm, zp, fx, fy, fz):
    """The interior gradient from its 32 voxels (see :func:`interior_gradient`).

    ``c`` is the centre cell's corners ``(c000, c001, c010, c011, c100, c101, c110, c111)``
    (``c_kji``: ``k`` along z, ``j`` along y, ``i`` along x); ``xm`` / ``xp`` the voxels
    at ``i0 - 1`` / ``i0 + 2`` for ``(j, k)`` in (0, 0), (1, 0), (0, 1), (1, 1); ``ym`` /
    ``yp`` those at ``j0 - 1`` / ``j0 + 2`` for ``(i, k)`` in the same order, ``zm`` /
    ``zp`` those at ``k0 - 1`` / ``k0 + 2`` for ``(i, j)``.
    """
    c000, c001, c010, c011, c100, c101, c110, c111 = c
    # x: columns i0 - 1 .. i0 + 2, each bilinear in (y, z)
    x0 = _bilerp(c000, c010, c100, c110, fy, fz)
    x1 = _bilerp(c001, c011, c101, c111, fy, fz)
    xlo = _bilerp(xm[0], xm[1], xm[2], xm[3], fy, fz)
    xhi = _bilerp(xp[0], xp[1], xp[2], xp[3], fy, fz)
    gx = 0.5 * ((x1 + fx * (xhi - x1)) - (xlo + fx * (x0 - xlo)))
    # y: rows j0 - 1 .. j0 + 2, each bilinear in (x, z)
    y0 = _bilerp(c000, c001, c100, c101, fx, fz)
    y1 = _bilerp(c010, c011, c110, c111, fx, fz)
    ylo = _bilerp(ym[0], ym[1], ym[2], ym[3], fx, fz)
    yhi = _bilerp(yp[0], yp[1], yp[2], yp[3], fx, fz)
    gy = 0.5 * ((y1 + fy * (yhi - y1)) - (ylo + fy * (y0 - ylo)))
    # z: slices k0 - 1 .. k0 + 2, each bilinear in (x, y)
    z0 = _bilerp(c000, c001, c010, c011, fx, fy)
    z1 = _bilerp(c100, c101, c110, c111, fx, fy)
    zlo = _bilerp(zm[0], zm[1], zm[2], zm[3], fx, fy)
    zhi = _bilerp(zp[0], zp[1], zp[2], zp[3], fx, fy)
    gz = 0.5 * ((z1 + fz * (zhi - z1)) - (zlo + fz * (z0 - zlo)))
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
