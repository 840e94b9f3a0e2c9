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

#: depth of a texel that no primitive covers
EMPTY = -1e30
#: below this a depth counts as empty (robust to the float32 rounding of EMPTY)
EMPTY_TEST = -1e29
#: secant (regula falsi) iterations after the linear search brackets a hit
SECANT_STEPS = 4
#: normals are stored as int8, scaled by this
NORMAL_SCALE = 127.0


@njit(cache=True, inline="always")
def _slab_tile(o, d, lo, hi, t0, t1):
    if d == 0.0:
        if o < lo or o > hi:
            return 1.0, 0.0
        return t0, t1
    a = (lo - o) / d
    b = (hi - o) / d
    if a > b:
        a, b = b, a
    return max(t0, a), min(t1, b)


@njit(cache=True, inline="always")
def _height(depth, x0, y0, r, s, t):
    """Bilinear height at texel coordinates ``(s, t)``, or EMPTY when a corner is empty."""
    i = min(max(int(s), 0), r - 2)
    j = min(max(int(t), 0), r - 2)
    fs = s - i
    ft = t - j
    h00 = depth[y0 + j, x0 + i]
    h10 = depth[y0 + j, x0 + i + 1]
    h01 = depth[y0 + j + 1, x0 + i]
    h11 = depth[y0 + j + 1, x0 + i + 1]
    if h00 < EMPTY_TEST or h10 < EMPTY_TEST or h01 < EMPTY_TEST or h11 < EMPTY_TEST:
        return EMPTY
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


@njit(cache=True)
def tile_hit(k, ox, oy, oz, dx, dy, dz, t_min, t_max, tile_proj, tile_h, tile_rect, depth):
    """First crossing of the ray with height-field tile ``k`` in ``[t_min, t_max]``.

    Linear search one texel per step along the ray's footprint in the tile, then
    regula falsi between the two samples that bracket a sign change of
    ``ray height - surface height``. Either crossing direction counts (surfaces
    are two-sided, as in the exact triangle test).

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
    ta, tb = _slab_tile(s0, ds, 0.0, r - 1.0, t_min, t_max)
    ta, tb = _slab_tile(u0, du, 0.0, r - 1.0, ta, tb)
    ta, tb = _slab_tile(h0, dh, tile_h[k, 0], tile_h[k, 1], ta, tb)
    if ta > tb:
        return math.inf, 0.0, 0.0
    # One sample per texel crossed (at least the two ends).
    steps = int(math.ceil(max(abs(ds), abs(du)) * (tb - ta))) + 1
    dt = (tb - ta) / steps
    t_prev = ta
    h = _height(depth, x0, y0, r, s0 + ta * ds, u0 + ta * du)
    f_prev = h0 + ta * dh - h
    valid_prev = h > EMPTY_TEST
    for i in range(1, steps + 1):
        t = ta + i * dt
        h = _height(depth, x0, y0, r, s0 + t * ds, u0 + t * du)
        valid = h > EMPTY_TEST
        f = h0 + t * dh - h
        if valid and valid_prev and (f <= 0.0) != (f_prev <= 0.0):
            # Regula falsi inside [t_prev, t].
            a, fa, b, fb = t_prev, f_prev, t, f
            for _ in range(SECANT_STEPS):
                if fa == fb:
                    break
                c = a - fa * (b - a) / (fb - fa)
                hc = _height(depth, x0, y0, r, s0 + c * ds, u0 + c * du)
                if hc < EMPTY_TEST:
                    break
                fc = h0 + c * dh - hc
                if (fc <= 0.0) == (fa <= 0.0):
                    a, fa = c, fc
                else:
                    b, fb = c, fc
            th = a - fa * (b - a) / (fb - fa) if fa != fb else a
            return th, s0 + th * ds, u0 + th * du
        t_prev = t
        f_prev = f
        valid_prev = valid
    return math.inf, 0.0, 0.0
