"""Transfer-function lookup, headlight Blinn-Phong and front-to-back compositing."""

from __future__ import annotations

import math

from numba import njit, types
from numba.extending import overload

from .borrow import NO_REFCOUNT
from .vectorize import load_run, run_loadable


# Layout of the ``shading`` parameter array passed to every marcher.
SHADING_ENABLED, SHADING_KA, SHADING_KD, SHADING_KS, SHADING_SHININESS = range(5)
SHADING_SIZE = 5


@njit(cache=True, inline="always")
def tf_alpha(table, v, v_lo, scale):
    """Opacity at value ``v`` plus the table position ``(i, f)`` for :func:`tf_color`.

    ``table`` is ``(n, 4)`` float32 with straight colour and step-corrected opacity;
    the entry position is ``x = (v - v_lo) * scale`` clamped to ``[0, n-1]``, and
    rows ``i = min(floor(x), n-2)`` and ``i+1`` are blended with weight ``f = x - i``.
    Opacity comes first because most samples in a sparse volume are transparent
    and never need their colour.
    """
    i, f = _table_position(table.shape[0], v, v_lo, scale)
    return i, f, (1.0 - f) * table[i, 3] + f * table[i + 1, 3]


@njit(cache=True)
def _table_position(n, v, v_lo, scale):
    """Row ``i`` and weight ``f`` of value ``v`` in a table of ``n`` rows (see :func:`tf_alpha`)."""
    # min / max rather than branches: the same values, and no branches to merge where
    # this is inlined into an inlined overload (Numba warned of it)
    x = min(max((v - v_lo) * scale, 0.0), n - 1.0)
    i = min(int(x), n - 2)
    return i, x - i


@njit(cache=True, inline="always")
def tf_color(table, i, f):
    """Straight colour at the table position returned by :func:`tf_alpha`."""
    g = 1.0 - f
    return (
        g * table[i, 0] + f * table[i + 1, 0],
        g * table[i, 1] + f * table[i + 1, 1],
        g * table[i, 2] + f * table[i + 1, 2],
    )


def tf_rgba(table, v, v_lo, scale):  # pragma: no cover - replaced by an overload in jitted code
    """``(a, r, g, b)`` at value ``v``: :func:`tf_alpha` and :func:`tf_color` at once, the
    same floats. For a C-contiguous float32 table the two rows are read as four pairs
    ``(r, g), (b, a)`` (:func:`.vectorize.load_run`): 4 loads instead of 8, which counts
    in the packets' lane loop (:mod:`.packet`), where every lane needs its colour anyway."""
    raise NotImplementedError("tf_rgba is only callable from jitted code")


@overload(tf_rgba, inline="always")
def _tf_rgba(table, v, v_lo, scale):
    if isinstance(table, types.Array) and table.ndim == 2 and run_loadable(table, 2):
        return _tf_rgba_pairs
    return _tf_rgba_items


def _tf_rgba_pairs(table, v, v_lo, scale):
    i, f = _table_position(table.shape[0], v, v_lo, scale)
    g = 1.0 - f
    r0, g0 = load_run(table, 4 * i, 2)
    b0, a0 = load_run(table, 4 * i + 2, 2)
    r1, g1 = load_run(table, 4 * i + 4, 2)
    b1, a1 = load_run(table, 4 * i + 6, 2)
    return (1.0 - f) * a0 + f * a1, g * r0 + f * r1, g * g0 + f * g1, g * b0 + f * b1


def _tf_rgba_items(table, v, v_lo, scale):
    i, f, a = tf_alpha(table, v, v_lo, scale)
    r, g, b = tf_color(table, i, f)
    return a, r, g, b


@njit(cache=True, inline="always")
def _power(x, s):
    """``x ** s`` for ``x`` in ``[0, 1]``: by repeated squaring when ``s`` is a whole
    number up to 1024 (the default shininess, 24, takes 7 multiplications where
    libm's ``pow`` took 4 % of a shaded isosurface frame), else by ``pow``. The two
    differ by a few ulps."""
    if 0.0 <= s <= 1024.0 and s == math.floor(s):
        n = int(s)
        r = 1.0
        b = x
        while n > 0:
            if n & 1:
                r *= b
            b *= b
            n >>= 1
        return r
    return x ** s


@njit(cache=True, **NO_REFCOUNT)
def blinn_phong(r, g, b, nx, ny, nz, dx, dy, dz, shading):
    """Shade straight colour ``(r, g, b)`` with a headlight (light at the eye).

    ``(nx, ny, nz)`` is the (unnormalised) world gradient and ``(dx, dy, dz)`` the
    unit ray direction. With the light at the eye, light, view and half vectors all
    equal ``-d``; the lighting is two-sided because a gradient has no inside.
    """
    ka = shading[SHADING_KA]
    kd = shading[SHADING_KD]
    ks = shading[SHADING_KS]
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    if length == 0.0:
        # Homogeneous region: no surface to light, keep the ambient + diffuse look.
        return min(r * (ka + kd), 1.0), min(g * (ka + kd), 1.0), min(b * (ka + kd), 1.0)
    ndl = abs(nx * dx + ny * dy + nz * dz) / length
    spec = ks * _power(ndl, shading[SHADING_SHININESS])
    diff = ka + kd * ndl
    return min(r * diff + spec, 1.0), min(g * diff + spec, 1.0), min(b * diff + spec, 1.0)


@njit(cache=True, **NO_REFCOUNT)
def write_pixel(out, py, px, r, g, b, a, background):
    """Store premultiplied ``(r, g, b, a)`` composited over ``background`` (straight RGBA)."""
    rest = (1.0 - a) * background[3]
    out[py, px, 0] = r + rest * background[0]
    out[py, px, 1] = g + rest * background[1]
    out[py, px, 2] = b + rest * background[2]
    out[py, px, 3] = a + rest
