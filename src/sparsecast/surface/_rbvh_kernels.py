"""Height-field tile intersection for RBVH leaves (Numba).

A tile ``k`` is an ``R x R`` grid of depths stored at ``atlas_depth[y0:y0+R, x0:x0+R]``
(``tile_rect[k] = (x0, y0, R)``) with a normal layer beside it. Its orthographic
projection ``tile_proj[k]`` (12 floats) is ``O, U, V, W``: a world point ``p`` has
texel coordinates ``s = (p - O) . U``, ``t = (p - O) . V`` in ``[0, R-1]`` (``U`` and
``V`` carry the inverse texel spacing) and height ``h = (p - O) . W`` along the unit
projection direction ``W``. Texels are vertex-centred, so the bilinear surface spans
the tile exactly. Empty texels hold :data:`EMPTY`; a cell with an empty corner has
no surface.
"""

from __future__ import annotations

import math

from numba import njit

from ..kernels.ray import inverse, slab

#: depth of a texel that no primitive covers
EMPTY = -1e30
#: below this a depth counts as empty (robust to the float32 rounding of EMPTY)
EMPTY_TEST = -1e29
#: secant (regula falsi) iterations after the linear search brackets a hit
SECANT_STEPS = 4
#: normals are stored as int8, scaled by this
NORMAL_SCALE = 127.0


@njit(cache=True, inline="always")
def _bilerp(h00, h10, h01, h11, fs, ft):
    """Bilinear interpolation at ``(fs, ft)`` in a cell (extrapolates outside ``[0, 1]^2``)."""
    return (1.0 - ft) * ((1.0 - fs) * h00 + fs * h10) + ft * ((1.0 - fs) * h01 + fs * h11)


@njit(cache=True)
def tile_normal(normal, x0, y0, r, s, t):
    """Bilinear unit normal from the int8 normal layer (unnormalised if all zero)."""
    i = min(max(int(s), 0), r - 2)
    j = min(max(int(t), 0), r - 2)
    fs = s - i
    ft = t - j
    w00 = (1.0 - fs) * (1.0 - ft)
    w10 = fs * (1.0 - ft)
    w01 = (1.0 - fs) * ft
    w11 = fs * ft
    y1, x1 = y0 + j, x0 + i
    nx = (w00 * normal[y1, x1, 0] + w10 * normal[y1, x1 + 1, 0]
          + w01 * normal[y1 + 1, x1, 0] + w11 * normal[y1 + 1, x1 + 1, 0])
    ny = (w00 * normal[y1, x1, 1] + w10 * normal[y1, x1 + 1, 1]
          + w01 * normal[y1 + 1, x1, 1] + w11 * normal[y1 + 1, x1 + 1, 1])
    nz = (w00 * normal[y1, x1, 2] + w10 * normal[y1, x1 + 1, 2]
          + w01 * normal[y1 + 1, x1, 2] + w11 * normal[y1 + 1, x1 + 1, 2])
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    if ln > 0.0:
        return nx / ln, ny / ln, nz / ln
    return 0.0, 0.0, 0.0


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
def tile_hit(k, ox, oy, oz, dx, dy, dz, t_min, t_max, tile_proj, tile_h, tile_rect, depth):
    """First crossing of the ray with height-field tile ``k`` in ``[t_min, t_max]``.

    The linear search visits the cells of the tile under the ray in order (a 2-D
    DDA, so no cell is skipped) and compares ray height and surface height where
    the ray enters and leaves each valid cell; a sign change is refined by regula
    falsi on that cell's bilinear patch. Either crossing direction counts
    (surfaces are two-sided, as in the exact triangle test). Cells with an empty
    corner hold no surface.

    Returns ``(t, s, u)``: the ray parameter (``inf`` on a miss) and the texel
    coordinates of the hit.
    """
    # Element reads, not row views: a view costs reference-count updates that
    # threads contend on in this innermost loop.
    x0 = tile_rect[k, 0]
    y0 = tile_rect[k, 1]
    r = tile_rect[k, 2]
    rx, ry, rz = ox - tile_proj[k, 0], oy - tile_proj[k, 1], oz - tile_proj[k, 2]
    ux, uy, uz = tile_proj[k, 3], tile_proj[k, 4], tile_proj[k, 5]
    vx, vy, vz = tile_proj[k, 6], tile_proj[k, 7], tile_proj[k, 8]
    wx, wy, wz = tile_proj[k, 9], tile_proj[k, 10], tile_proj[k, 11]
    s0 = rx * ux + ry * uy + rz * uz
    ds = dx * ux + dy * uy + dz * uz
    u0 = rx * vx + ry * vy + rz * vz
    du = dx * vx + dy * vy + dz * vz
    h0 = rx * wx + ry * wy + rz * wz
    dh = dx * wx + dy * wy + dz * wz
    inv_s, flat_s = inverse(ds)
    inv_u, flat_u = inverse(du)
    inv_h, flat_h = inverse(dh)
    ta, tb = slab(h0, inv_h, flat_h, tile_h[k, 0], tile_h[k, 1], t_min, t_max)
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
        h00 = depth[y0 + j, x0 + i]
        h10 = depth[y0 + j, x0 + i + 1]
        h01 = depth[y0 + j + 1, x0 + i]
        h11 = depth[y0 + j + 1, x0 + i + 1]
        if h00 > EMPTY_TEST and h10 > EMPTY_TEST and h01 > EMPTY_TEST and h11 > EMPTY_TEST:
            # Bilinear patches agree on a shared border, so the previous cell's
            # exit value is this cell's entry value.
            if have_f_in:
                fa = f_in
            else:
                fa = h0 + t * dh - _bilerp(h00, h10, h01, h11, s0 + t * ds - i, u0 + t * du - j)
            fb = h0 + t_exit * dh - _bilerp(h00, h10, h01, h11, s0 + t_exit * ds - i, u0 + t_exit * du - j)
            if (fa <= 0.0) != (fb <= 0.0):
                a, b = t, t_exit
                for _ in range(SECANT_STEPS):
                    if fa == fb:
                        break
                    c = a - fa * (b - a) / (fb - fa)
                    fc = h0 + c * dh - _bilerp(h00, h10, h01, h11, s0 + c * ds - i, u0 + c * du - j)
                    if (fc <= 0.0) == (fa <= 0.0):
                        a, fa = c, fc
                    else:
                        b, fb = c, fc
                th = a - fa * (b - a) / (fb - fa) if fa != fb else a
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
