"""Transfer-function range queries: is the opacity zero for every value in [lo, hi]?

One implementation, used by :meth:`TransferFunction.classify` (bricks, cells,
k-d tree nodes) and by kernels that classify on the fly (the min-max grid).
"""

from __future__ import annotations

import math

from numba import njit, prange

#: Widening of a queried range ``[lo, hi]`` on each side, as a fraction of its span
#: ``hi - lo`` (value space, not table entries). Float rounding can put a trilinear
#: sample just outside its region's [min, max]: a rounded difference of two voxel
#: values, or a lattice point an ulp outside the volume box that extrapolates by an
#: ulp (see ``kernels.sample._axis``). Every such error is a few ulps *of the span*
#: (the lerp ``a + f * (b - a)`` overshoots only through ``f * (b - a)``); a
#: constant region, all-zero bricks included, interpolates to its value exactly
#: (``a + f * 0 == a``) and gets no widening at all. 1e-6 of the span covers
#: coordinate errors up to 1e-6 cell, and stays below 0.005 table entries for any
#: region inside the TF range, so it changes no answer that is not on a hair.
SPAN_MARGIN = 1e-6


@njit(cache=True, inline="always")
def entry_span(v_lo, scale, n_entries, lo, hi):
    """Table entries ``first..last`` that a lookup of any value in ``[lo, hi]`` touches.

    A lookup blends entries ``i = floor(x)`` and ``i + 1`` with weights ``1 - f`` and
    ``f = x - i`` at ``x = (v - v_lo) * scale`` clamped to ``[0, n-1]`` (the last
    entry is reached as ``i = n-2, f = 1``). An entry of weight 0 contributes
    nothing, so values in ``[lo, hi]`` touch exactly ``floor(x0)..ceil(x1)``: a
    range that ends on an entry (``x1`` integral, e.g. a TF that is zero at the data
    minimum and ramps up from there) does not touch the next one. The range is
    first widened by :data:`SPAN_MARGIN` of its span, for rounding of samples.
    """
    top = n_entries - 1.0
    pad = SPAN_MARGIN * (hi - lo)
    if not pad >= 0.0:  # lo == hi == +-inf: a NaN pad would turn every answer to NaN
        pad = 0.0
    x0 = min(max((lo - pad - v_lo) * scale, 0.0), top)
    x1 = min(max((hi + pad - v_lo) * scale, 0.0), top)
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
