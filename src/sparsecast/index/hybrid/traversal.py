"""Hybrid-grid traversal: shallow k-d tree leaves front to back, and inside each
leaf's interval a DDA over the 16^3 macrocell grid that yields its non-empty runs.

Exactness combines the two iterators' arguments: the leaf list is walked as in
:mod:`sparsecast.index.kdtree.traversal` (widened, clipped intervals), and inside
a leaf's interval the DDA classifies exactly as the grid does over a whole ray
(:mod:`sparsecast.index.grid.traversal`), whose cells' one-voxel apron covers a
sample that rounding attributes to a neighbouring cell.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from numba.extending import overload

from ..grid.traversal import GridRecord, dda_next, dda_start
from ..interval import next_interval, record_class, start_ray
from ..kdtree.traversal import KdListRecord, next_listed_leaf

__all__ = ["HybridRecord"]


class HybridRecord(NamedTuple):
    """A frame's sorted leaf list and the grid walked inside each leaf."""

    leaves: KdListRecord
    grid: GridRecord


@overload(start_ray, jit_options={"cache": True}, inline="always")
def _start(record, scratch, ray, t_lo, t_hi):
    if record_class(record) is HybridRecord:

        def impl(record, scratch, ray, t_lo, t_hi):
            # A finished DDA state (empty walk): the first call moves on to the first leaf.
            g = dda_start(record.grid, ray, t_lo, -math.inf)
            return (0, t_lo, t_hi, g)

        return impl


@overload(next_interval, jit_options={"cache": True}, inline="always")
def _next(record, scratch, ray, state, t_covered):
    if record_class(record) is HybridRecord:

        def impl(record, scratch, ray, state, t_covered):
            j, t_lo, t_hi, g = state
            while True:
                t0, t1, g = dda_next(record.grid, g)
                if t0 <= t1:
                    return t0, t1, (j, t_lo, t_hi, g)
                l0, l1, j = next_listed_leaf(record.leaves, ray, j, t_lo, t_hi)
                if l0 > l1:
                    return t0, t1, (j, t_lo, t_hi, g)
                g = dda_start(record.grid, ray, l0, l1)

        return impl
