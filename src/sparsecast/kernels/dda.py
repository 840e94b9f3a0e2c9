"""3-D DDA over a uniform grid (Amanatides & Woo 1987), one axis at a time."""

from __future__ import annotations

import math

from numba import njit

from .classify import range_is_empty
from .march import march_interval


@njit(cache=True, inline="always")
def dda_axis(o, d, t, cell, n_cells):
    """Start a DDA on one axis at ray parameter ``t``.

    Cells have edge ``cell`` (index units) and cell ``c`` spans ``[c*cell, (c+1)*cell]``.

    Returns
    -------
    c : int
        Cell containing ``o + t d``, clamped to ``[0, n_cells-1]`` (the point may
        sit an ulp outside the grid when ``t`` is the box entry).
    step : int
        +1, -1, or 0 for a ray parallel to this axis.
    t_max : float
        Ray parameter of the next cell boundary on this axis (inf when parallel).
    t_delta : float
        Ray parameter between boundaries (inf when parallel).
    """
    c = int(math.floor((o + t * d) / cell))
    c = min(max(c, 0), n_cells - 1)
    if d > 0.0:
        return c, 1, ((c + 1) * cell - o) / d, cell / d
    if d < 0.0:
        return c, -1, (c * cell - o) / d, -cell / d
    return c, 0, math.inf, math.inf


@njit(cache=True, error_model="numpy")
def dda_march(
    flat, nx, ny, nz, cell, ncx, ncy, ncz, occupied, cell_min, cell_max, use_minmax, prefix,
    table, v_lo, scale, ox, oy, oz, dx, dy, dz, wdx, wdy, wdz, inv_spacing, dt,
    t_enter, t_far, k_next, r, g, b, a, ert, shading,
):
    """March the non-empty cells of a macrocell grid along ``[t_enter, t_far]``.

    Used by the grid marcher over a whole ray and by the hybrid grids inside each
    k-d tree leaf. Runs of consecutive non-empty cells are marched as one segment
    (:func:`.march.march_interval`, global lattice, ``k_next`` carried in and out):
    fewer restarts of the sampling loop, the same samples. A cell is non-empty by
    ``occupied`` (pre-classified) or, with ``use_minmax``, by the TF range query on
    ``[cell_min, cell_max]`` and ``prefix``. Leaving the grid a rounding error
    before ``t_far`` ends the walk as if at ``t_far``.

    Returns ``(r, g, b, a, k_next, n_samples, n_nonempty)``.
    """
    n_samples = 0
    n_nonempty = 0
    cx, sx, tmx, tdx = dda_axis(ox, dx, t_enter, cell, ncx)
    cy, sy, tmy, tdy = dda_axis(oy, dy, t_enter, cell, ncy)
    cz, sz, tmz, tdz = dda_axis(oz, dz, t_enter, cell, ncz)
    seg_open = False
    seg_t0 = 0.0
    while True:
        if tmx <= tmy and tmx <= tmz:
            axis = 0
            t_exit = tmx
            leaves = cx + sx < 0 or cx + sx >= ncx
        elif tmy <= tmz:
            axis = 1
            t_exit = tmy
            leaves = cy + sy < 0 or cy + sy >= ncy
        else:
            axis = 2
            t_exit = tmz
            leaves = cz + sz < 0 or cz + sz >= ncz
        last = leaves or t_exit >= t_far
        if last:
            t_exit = t_far
        if use_minmax:
            full = not range_is_empty(prefix, v_lo, scale, cell_min[cz, cy, cx], cell_max[cz, cy, cx])
        else:
            full = occupied[cz, cy, cx] != 0
        if full and not seg_open:
            seg_open = True
            seg_t0 = t_enter
        if seg_open and (not full or last):
            seg_open = False
            r, g, b, a, k_next, ns, nne = march_interval(
                flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
                wdx, wdy, wdz, inv_spacing, dt, seg_t0, t_exit if full else t_enter,
                k_next, r, g, b, a, ert, shading,
            )
            n_samples += ns
            n_nonempty += nne
            if a >= ert:
                break
        if last:
            break
        t_enter = t_exit
        if axis == 0:
            cx += sx
            tmx += tdx
        elif axis == 1:
            cy += sy
            tmy += tdy
        else:
            cz += sz
            tmz += tdz
    return r, g, b, a, k_next, n_samples, n_nonempty
