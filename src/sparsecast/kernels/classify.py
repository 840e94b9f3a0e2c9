"""Transfer-function range queries: is the opacity zero for every value in [lo, hi]?

One implementation, used by :meth:`TransferFunction.classify` (bricks, cells,
k-d tree nodes) and by kernels that classify on the fly (the min-max grid).
"""

from __future__ import annotations

import math

from numba import njit, prange

#: Widening of a queried range, in table entries. It keeps answers conservative
#: when float rounding (trilinear interpolation in float, a lattice point an ulp
#: outside its cell) puts a sample just outside its region's [min, max].
MARGIN = 1e-3


@njit(cache=True, inline="always")
def entry_span(v_lo, scale, n_entries, lo, hi):
    """Table entries ``first..last`` that a lookup of any value in ``[lo, hi]`` touches.

    Lookups blend entries ``floor(x)`` and ``floor(x) + 1`` at ``x = (v - v_lo) * scale``
    clamped to ``[0, n-1]``, so ``floor(x0)..ceil(x1)`` covers every entry with a
    non-zero weight.
    """
    top = n_entries - 1.0
    x0 = min(max((lo - v_lo) * scale - MARGIN, 0.0), top)
    x1 = min(max((hi - v_lo) * scale + MARGIN, 0.0), top)
    return int(math.floor(x0)), int(math.ceil(x1))


@njit(cache=True, inline="always")
def range_is_empty(prefix, v_lo, scale, lo, hi):
    """True when the TF opacity is zero for every value in ``[lo, hi]`` (O(1)).

    ``prefix[i]`` counts the table entries among ``[0, i)`` with non-zero opacity
    (length ``n_entries + 1``).
    """
    first, last = entry_span(v_lo, scale, prefix.shape[0] - 1, lo, hi)
    return prefix[last + 1] - prefix[first] == 0


#: below this many ranges a serial loop wins: waking Numba's thread pool costs more
#: (milliseconds on a loaded 2-core machine) than classifying 10^5 ranges (~0.3 ms)
PARALLEL_MIN = 1 << 18


@njit(cache=True)
def _classify_serial(prefix, v_lo, scale, vmin, vmax, out):
    for i in range(vmin.shape[0]):
        out[i] = not range_is_empty(prefix, v_lo, scale, vmin[i], vmax[i])


@njit(cache=True, parallel=True)
def _classify_parallel(prefix, v_lo, scale, vmin, vmax, out):
    for i in prange(vmin.shape[0]):
        out[i] = not range_is_empty(prefix, v_lo, scale, vmin[i], vmax[i])


def classify_ranges(prefix, v_lo, scale, vmin, vmax, out) -> None:
    """``out[i] = not range_is_empty(..., vmin[i], vmax[i])`` for flat arrays."""
    kernel = _classify_parallel if vmin.shape[0] >= PARALLEL_MIN else _classify_serial
    kernel(prefix, v_lo, scale, vmin, vmax, out)
