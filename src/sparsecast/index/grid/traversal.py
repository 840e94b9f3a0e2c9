"""Macrocell-grid traversal: a 3-D DDA over cells (Amanatides & Woo 1987) that
yields runs of consecutive non-empty cells.

Exactness: consecutive cells share their boundary parameter, so the runs this
yields cover every non-empty cell the ray crosses; the driver marches each run
on the global lattice. A sample that rounding attributes to a neighbouring cell
is within one voxel of it, which the cells' one-voxel apron covers, so skipping
a cell classified empty never drops a sample of non-zero opacity. Leaving the
grid a rounding error before the interval's end ends the walk as if at its end.

The DDA is usable on its own over any ``[t0, t1]`` (:func:`dda_start`,
:func:`dda_next`): the hybrid grids run it inside each k-d tree leaf.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.extending import overload

from ...kernels.borrow import NO_REFCOUNT
from ...kernels.classify import range_is_empty
from ..interval import next_interval, record_class, start_ray

__all__ = ["GridRecord", "dda_start", "dda_next"]


class GridRecord(NamedTuple):
    """Arrays of a macrocell grid (cell ``c`` spans ``[c*cell, (c+1)*cell]`` per axis).

    Attributes
    ----------
    cell : float
        Voxels per cell edge.
    use_minmax : bool
        Classify cells on the fly from ``[cell_min, cell_max]`` and ``prefix``
        (min-max grid) instead of reading ``occupied`` (pre-classified).
    occupied : (ncz, ncy, ncx) uint8
        1 for a non-empty cell (pre-classified; else a (1, 1, 1) dummy).
    cell_min, cell_max : (ncz, ncy, ncx) float64
        Value ranges with apron (min-max; else (1, 1, 1) dummies).
    prefix : (n + 1,) int64
        The TF's prefix count of non-zero opacity entries.
    v_lo, scale : float
        The TF's table mapping.
    ncx, ncy, ncz : int
        Cell counts.
    """

    cell: float
    use_minmax: bool
    occupied: np.ndarray
    cell_min: np.ndarray
    cell_max: np.ndarray
    prefix: np.ndarray
    v_lo: float
    scale: float
    ncx: int
    ncy: int
    ncz: int


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def dda_axis(o, d, t, cell, n_cells):
    """Start a DDA on one axis at ray parameter ``t``.

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


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def dda_start(grid, ray, t0, t1):
    """DDA state at ``t0`` for a walk that ends at ``t1``.

    The state is ``(cx, cy, cz, sx, sy, sz, tmx, tmy, tmz, tdx, tdy, tdz, t_enter, t_end, done)``.
    """
    ox, oy, oz, dx, dy, dz = ray
    cx, sx, tmx, tdx = dda_axis(ox, dx, t0, grid.cell, grid.ncx)
    cy, sy, tmy, tdy = dda_axis(oy, dy, t0, grid.cell, grid.ncy)
    cz, sz, tmz, tdz = dda_axis(oz, dz, t0, grid.cell, grid.ncz)
    return (cx, cy, cz, sx, sy, sz, tmx, tmy, tmz, tdx, tdy, tdz, t0, t1, t0 > t1)


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def dda_next(grid, state):
    """The next run of consecutive non-empty cells: ``(t0, t1, state)``; ``t0 > t1`` at the end."""
    cx, cy, cz, sx, sy, sz, tmx, tmy, tmz, tdx, tdy, tdz, t_enter, t_end, done = state
    seg_open = False
    seg_t0 = 0.0
    while not done:
        if tmx <= tmy and tmx <= tmz:
            axis = 0
            t_exit = tmx
            leaves = cx + sx < 0 or cx + sx >= grid.ncx
        elif tmy <= tmz:
            axis = 1
            t_exit = tmy
            leaves = cy + sy < 0 or cy + sy >= grid.ncy
        else:
            axis = 2
            t_exit = tmz
            leaves = cz + sz < 0 or cz + sz >= grid.ncz
        last = leaves or t_exit >= t_end
        if last:
            t_exit = t_end
        if grid.use_minmax:
            full = not range_is_empty(grid.prefix, grid.v_lo, grid.scale,
                                      grid.cell_min[cz, cy, cx], grid.cell_max[cz, cy, cx])
        else:
            full = grid.occupied[cz, cy, cx] != 0
        if full and not seg_open:
            seg_open = True
            seg_t0 = t_enter
        close = seg_open and (not full or last)
        seg_t1 = t_exit if full else t_enter
        if last:
            done = True
        else:
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
        if close:
            return seg_t0, seg_t1, (cx, cy, cz, sx, sy, sz, tmx, tmy, tmz, tdx, tdy, tdz, t_enter, t_end, done)
    return math.inf, -math.inf, (cx, cy, cz, sx, sy, sz, tmx, tmy, tmz, tdx, tdy, tdz, t_enter, t_end, True)


@overload(start_ray, jit_options={"cache": True}, inline="always")
def _start(record, scratch, ray, t_lo, t_hi):
    if record_class(record) is GridRecord:
        return lambda record, scratch, ray, t_lo, t_hi: dda_start(record, ray, t_lo, t_hi)


@overload(next_interval, jit_options={"cache": True}, inline="always")
def _next(record, scratch, ray, state, t_covered):
    if record_class(record) is GridRecord:
        return lambda record, scratch, ray, state, t_covered: dda_next(record, state)
