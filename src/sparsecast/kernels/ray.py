"""Ray/box clipping and the global sampling lattice ``t_k = k * dt``."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def _slab(o, d, lo, hi, tmin, tmax):
    """Intersect ``[tmin, tmax]`` with one slab ``lo <= o + t d <= hi``.

    Axis-parallel rays (``d == 0``) are handled explicitly rather than through
    ``1/0 = inf``: with ``o`` exactly on a slab plane the IEEE route gives
    ``0 * inf = NaN``, which would silently drop the ray.
    """
    if d == 0.0:
        if o < lo or o > hi:
            return 1.0, 0.0  # empty interval
        return tmin, tmax
    inv = 1.0 / d
    t0 = (lo - o) * inv
    t1 = (hi - o) * inv
    if t0 > t1:
        t0, t1 = t1, t0
    return max(tmin, t0), min(tmax, t1)


@njit(cache=True)
def clip_box(ox, oy, oz, dx, dy, dz, bx0, by0, bz0, bx1, by1, bz1):
    """Parametric interval ``(t_near, t_far)`` of a ray inside an axis-aligned box.

    The interval is empty (``t_near > t_far``) when the ray misses. Boxes may be
    flat (``lo == hi`` on an axis): a ray in that plane still gets an interval.
    """
    tn, tf = _slab(ox, dx, bx0, bx1, -math.inf, math.inf)
    tn, tf = _slab(oy, dy, by0, by1, tn, tf)
    tn, tf = _slab(oz, dz, bz0, bz1, tn, tf)
    return tn, tf


@njit(cache=True)
def lattice_range(t_near, t_far, dt):
    """Indices ``k0..k1`` (inclusive) of lattice samples ``k * dt`` in ``[t_near, t_far]``.

    Samples behind the eye (``t < 0``) are never taken. Returns ``k1 < k0`` when
    no sample lies in the interval.
    """
    if t_near < 0.0:
        t_near = 0.0
    if t_far < t_near:
        return 1, 0
    k0 = math.ceil(t_near / dt)
    k1 = math.floor(t_far / dt)
    return k0, k1
