"""Height-field tile intersection for RBVH leaves (Numba).

A tile ``k`` is an ``R x R`` grid of depths stored row by row at
``depth[o : o + R * R]`` of the texel pool, with a normal layer aligned with it
(:mod:`.atlas`). Its record ``tiles[k]`` is one 64-byte line of 16 words
(:data:`TILE_WORDS`): the orthographic projection (12 floats, ``O, U, V, W``),
the valid texels' height range at :data:`TILE_H`, and as int32 bits (read through
the int32 view ``tiles_i``) the pool offset ``o`` at :data:`TILE_OFFSET` and ``R``
at :data:`TILE_RES`. A world point ``p`` has
texel coordinates ``s = (p - O) . U``, ``t = (p - O) . V`` in ``[0, R-1]`` (``U`` and
``V`` carry the inverse texel spacing) and height ``h = (p - O) . W`` along the unit
projection direction ``W``. Texels are vertex-centred, so the bilinear surface spans
the tile exactly. Empty texels hold :data:`EMPTY`; a cell with an empty corner has
no surface.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels.ray import inverse, slab

#: depth of a texel that no primitive covers
EMPTY = -1e30
#: below this a depth counts as empty (robust to the float32 rounding of EMPTY)
EMPTY_TEST = -1e29
#: normals are stored as int8, scaled by this
NORMAL_SCALE = 127.0
#: words of a tile record: one 64-byte cache line
TILE_WORDS = 16
#: record word of the lower height bound (the upper follows)
TILE_H = 12
#: record words (int32 bits) of the pool offset and of the edge R
TILE_OFFSET = 14
TILE_RES = 15


@njit(cache=True, inline="always")
def _bilerp(h00, h10, h01, h11, fs, ft):
    """Bilinear interpolation at ``(fs, ft)`` in a cell (extrapolates outside ``[0, 1]^2``)."""
    return (1.0 - ft) * ((1.0 - fs) * h00 + fs * h10) + ft * ((1.0 - fs) * h01 + fs * h11)


@njit(cache=True)
def tile_normal(normal, o, r, s, t):
    """Bilinear unit normal at texel coordinates ``(s, t)`` of the tile at pool offset ``o``
    with edge ``r``, from the int8 normal layer (zero if the four normals cancel)."""
    i = min(max(int(s), 0), r - 2)
    j = min(max(int(t), 0), r - 2)
    fs = s - i
    ft = t - j
    w00 = (1.0 - fs) * (1.0 - ft)
    w10 = fs * (1.0 - ft)
    w01 = (1.0 - fs) * ft
    w11 = fs * ft
    a = o + j * r + i
    nx = (w00 * normal[a, 0] + w10 * normal[a + 1, 0]
          + w01 * normal[a + r, 0] + w11 * normal[a + r + 1, 0])
    ny = (w00 * normal[a, 1] + w10 * normal[a + 1, 1]
          + w01 * normal[a + r, 1] + w11 * normal[a + r + 1, 1])
    nz = (w00 * normal[a, 2] + w10 * normal[a + 1, 2]
          + w01 * normal[a + r, 2] + w11 * normal[a + r + 1, 2])
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    if ln > 0.0:
        return nx / ln, ny / ln, nz / ln
    return 0.0, 0.0, 0.0


@njit(cache=True, inline="always")
def _patch_root(h00, h10, h01, h11, fs, ft, ds, du, dh, fa, fb, ta, tb):
    """The first ``t`` in ``[ta, tb]`` where the ray meets a cell's bilinear patch, in
    closed form; ``inf`` if it does not.

    Along the ray the patch height is a quadratic in ``t`` (bilinear in ``s`` and
    ``u``, each linear in ``t``), so ray height minus patch height is, from the
    bracket's start, ``f(ta + x) = fa + b x + a x^2`` with ``fs, ft`` the cell
    fractions at ``ta``, and ``fa``, ``fb`` its known values at the two ends. Where
    they differ in sign one root lies inside; the numerically stable form of the
    quadratic formula gives it with one square root and two divisions (regula falsi
    took four dependent steps, a division and a patch evaluation each, and still
    left an error). Where they agree the ray may still dip through the patch and
    back within the cell (two roots, on a ridge or a fold the ray grazes): that is
    the case when the parabola's vertex lies inside the bracket with the other
    sign, and the first root is then the smaller one.
    """
    e = h11 - h10 - h01 + h00
    a = -e * ds * du
    b = dh - ((h10 - h00) * ds + (h01 - h00) * du + e * (fs * du + ft * ds))
    length = tb - ta
    if (fa <= 0.0) == (fb <= 0.0):
        if a == 0.0:
            return math.inf  # linear along the ray: no sign change, no root
        xv = -0.5 * b / a
        if not 0.0 < xv < length or ((fa + xv * (b + a * xv)) <= 0.0) == (fa <= 0.0):
            return math.inf
        hi = xv  # two roots, one on each side of the vertex: the first lies in [0, xv]
    else:
        hi = length
    disc = max(b * b - 4.0 * a * fa, 0.0)
    q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
    # Roots fa / q and q / a: the one in the bracket (the other lies outside it, or
    # past the vertex).
    x = fa / q if q != 0.0 else 0.0
    if not 0.0 <= x <= hi and a != 0.0:
        x = q / a
    return ta + min(max(x, 0.0), hi)


@njit(cache=True, inline="always")
def _border(c, o, d, inv):
    """Ray parameter where coordinate ``o + t d`` leaves cell ``[c, c+1]`` (inf if never);
    ``inv = 1 / d``, taken once per tile: the search steps cells without a division."""
    if d > 0.0:
        return (c + 1.0 - o) * inv
    if d < 0.0:
        return (c - o) * inv
    return math.inf


@njit(cache=True)
def tile_hit(k, ox, oy, oz, dx, dy, dz, t_min, t_max, tiles, tiles_i, depth):
    """First crossing of the ray with height-field tile ``k`` in ``[t_min, t_max]``.

    The linear search visits the cells of the tile under the ray in order (a 2-D
    DDA, so no cell is skipped) and compares ray height and surface height where
    the ray enters and leaves each valid cell; a sign change is solved in closed
    form on that cell's bilinear patch (:func:`_patch_root`). Either crossing direction counts
    (surfaces are two-sided, as in the exact triangle test). Cells with an empty
    corner hold no surface.

    Returns ``(t, s, u)``: the ray parameter (``inf`` on a miss) and the texel
    coordinates of the hit. ``tiles`` (T, 16) float32 are the tile records and
    ``tiles_i`` their int32 view; ``depth`` (N,) float32 is the texel pool.
    """
    # Element reads, not row views: a view costs reference-count updates that
    # threads contend on in this innermost loop.
    o = tiles_i[k, TILE_OFFSET]
    r = tiles_i[k, TILE_RES]
    rx, ry, rz = ox - tiles[k, 0], oy - tiles[k, 1], oz - tiles[k, 2]
    ux, uy, uz = tiles[k, 3], tiles[k, 4], tiles[k, 5]
    vx, vy, vz = tiles[k, 6], tiles[k, 7], tiles[k, 8]
    wx, wy, wz = tiles[k, 9], tiles[k, 10], tiles[k, 11]
    s0 = rx * ux + ry * uy + rz * uz
    ds = dx * ux + dy * uy + dz * uz
    u0 = rx * vx + ry * vy + rz * vz
    du = dx * vx + dy * vy + dz * vz
    h0 = rx * wx + ry * wy + rz * wz
    dh = dx * wx + dy * wy + dz * wz
    inv_s, flat_s = inverse(ds)
    inv_u, flat_u = inverse(du)
    inv_h, flat_h = inverse(dh)
    ta, tb = slab(h0, inv_h, flat_h, tiles[k, TILE_H], tiles[k, TILE_H + 1], t_min, t_max)
    ta, tb = slab(s0, inv_s, flat_s, 0.0, r - 1.0, ta, tb)
    ta, tb = slab(u0, inv_u, flat_u, 0.0, r - 1.0, ta, tb)
    if ta > tb:
        return math.inf, 0.0, 0.0
    # The cell holding the segment's start (clamped: the entry point may sit
    # exactly on the far border).
    t = ta
    i = min(max(int(math.floor(s0 + t * ds)), 0), r - 2)
    j = min(max(int(math.floor(u0 + t * du)), 0), r - 2)
    step_i = 1 if ds > 0.0 else -1
    step_j = 1 if du > 0.0 else -1
    # Where the ray leaves the current cell's column and row: recomputed from the
    # cell index at each step (not accumulated), so rounding does not drift.
    t_i = _border(i, s0, ds, inv_s)
    t_j = _border(j, u0, du, inv_u)
    f_in = 0.0
    have_f_in = False  # f at the entry point, carried over from the previous valid cell
    for _ in range(2 * r + 2):
        t_exit = min(t_i, t_j, tb)
        if t_exit < t:
            t_exit = t
        a0 = o + j * r + i
        # Heights as float64 (np.float64: Numba's float() keeps a float32 a float32):
        # the patch's differences (its twist h11 - h10 - h01 + h00 above all) taken
        # in float32 put the root up to ~2e-7 off in t.
        h00 = np.float64(depth[a0])
        h10 = np.float64(depth[a0 + 1])
        h01 = np.float64(depth[a0 + r])
        h11 = np.float64(depth[a0 + r + 1])
        if h00 > EMPTY_TEST and h10 > EMPTY_TEST and h01 > EMPTY_TEST and h11 > EMPTY_TEST:
            # Bilinear patches agree on a shared border, so the previous cell's
            # exit value is this cell's entry value.
            if have_f_in:
                fa = f_in
            else:
                fa = h0 + t * dh - _bilerp(h00, h10, h01, h11, s0 + t * ds - i, u0 + t * du - j)
            fb = h0 + t_exit * dh - _bilerp(h00, h10, h01, h11, s0 + t_exit * ds - i, u0 + t_exit * du - j)
            th = _patch_root(h00, h10, h01, h11, s0 + t * ds - i, u0 + t * du - j, ds, du, dh, fa, fb, t, t_exit)
            if th <= t_exit:
                return th, s0 + th * ds, u0 + th * du
            f_in = fb
            have_f_in = True
        else:
            have_f_in = False
        if t_exit >= tb:
            break
        # Step into the neighbour across the nearer border.
        if t_i <= t_j:
            i += step_i
            if i < 0 or i > r - 2:
                break
            t_i = _border(i, s0, ds, inv_s)
        else:
            j += step_j
            if j < 0 or j > r - 2:
                break
            t_j = _border(j, u0, du, inv_u)
        t = t_exit
    return math.inf, 0.0, 0.0
