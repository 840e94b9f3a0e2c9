"""3-D DDA over a uniform grid (Amanatides & Woo 1987), one axis at a time."""

from __future__ import annotations

import math

from numba import njit


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
