"""Hybrid grids (Zellmann, Meurer & Lang, IEEE VIS 2019): a shallow k-d tree whose
leaves are traversed with a DDA over a 16^3 macrocell grid.

The shallow tree removes the large empty regions around the data with a few
leaves sorted once per frame; inside a leaf the grid skips the remaining holes.

``hybrid-pc`` pre-classifies the grid: its occupancy is read off the partial SVTs
that the tree construction builds anyway (a grid cell is non-empty when it holds
an occupied cell, whose apron makes this conservative like the grid's own
classification). ``hybrid-mm`` keeps the per-cell value ranges with apron
(``Volume.brick_stats(16)``, cached per volume) and classifies cells with the TF
range query during traversal.

Arrays: those of :class:`~sparsecast.index.kdtree.KdTree`, plus ``cell`` (16) and
``occupied`` (hybrid-pc) or ``cell_min``/``cell_max`` (hybrid-mm), shaped
``(ncz, ncy, ncx)`` with grid cell ``g`` spanning index coordinates
``[g * cell, (g + 1) * cell]`` as in :mod:`sparsecast.index.grid`.
"""

from __future__ import annotations

import time

import numpy as np

from ..base import View
from ..grid.traversal import GridRecord
from ..kdtree import occupancy
from ..kdtree.build import ShallowKdTree
from ..registry import register_index
from .traversal import HybridRecord

__all__ = ["HybridPreclassified", "HybridMinMax"]

#: macrocell edge of the hybrid grid (voxel cells); must divide the SVT brick (32)
HYBRID_CELL = 16

#: stand-ins for the arrays a grid kind does not read (one record type for both kinds)
_NO_MASK = np.zeros((1, 1, 1), np.uint8)
_NO_RANGE = np.zeros((1, 1, 1), np.float64)


def _grid(index, use_minmax: bool, occupied, cell_min, cell_max) -> GridRecord:
    ncz, ncy, ncx = (cell_min if use_minmax else occupied).shape
    return GridRecord(
        cell=float(index.cell), use_minmax=use_minmax, occupied=occupied, cell_min=cell_min,
        cell_max=cell_max, prefix=index.tf.prefix, v_lo=float(index.tf.value_range[0]),
        scale=float(index.tf.scale), ncx=ncx, ncy=ncy, ncz=ncz,
    )


@register_index
class HybridPreclassified(ShallowKdTree):
    """Shallow k-d tree + pre-classified 16^3 grid (the grid from the SVTs).

    Parameters: see :class:`~sparsecast.index.kdtree.KdTree`.
    """

    name = "hybrid-pc"
    #: the grid's cell boundaries are not grown, so the occupancy keeps the apron
    apron = True

    def __init__(self, volume, tf, **options) -> None:
        super().__init__(volume, tf, **options)
        self.cell = HYBRID_CELL
        t0 = time.perf_counter()
        ncz, ncy, ncx = self.cells.shape
        shape = tuple(-(-n // self.cell) for n in (ncz, ncy, ncx))
        self.occupied = np.empty(shape, np.uint8)
        c = self.cells
        occupancy.block_occupancy(c.svt, c.bslot, c.bcount, self.cell, self.occupied)
        self.build_phases["grid"] = (time.perf_counter() - t0) * 1e3
        self.nbytes += int(self.occupied.nbytes)

    def traversal_record(self, view: View) -> HybridRecord:
        grid = _grid(self, False, self.occupied, _NO_RANGE, _NO_RANGE)
        return HybridRecord(self.list_record(view), grid)

    def stats(self) -> dict:
        s = super().stats()
        s.update(cell=self.cell, grid_occupancy=float(self.occupied.mean()))
        return s


@register_index
class HybridMinMax(ShallowKdTree):
    """Shallow k-d tree + min-max 16^3 grid classified during traversal.

    Parameters: see :class:`~sparsecast.index.kdtree.KdTree`.
    """

    name = "hybrid-mm"
    #: the grid's cell boundaries are not grown, so the occupancy keeps the apron
    apron = True

    def __init__(self, volume, tf, **options) -> None:
        super().__init__(volume, tf, **options)
        self.cell = HYBRID_CELL
        t0 = time.perf_counter()
        stats = volume.brick_stats(self.cell)  # cached per volume
        self.cell_min = stats.vmin
        self.cell_max = stats.vmax
        self.build_phases["grid"] = (time.perf_counter() - t0) * 1e3
        self.nbytes += int(self.cell_min.nbytes + self.cell_max.nbytes)

    def traversal_record(self, view: View) -> HybridRecord:
        grid = _grid(self, True, _NO_MASK, self.cell_min, self.cell_max)
        return HybridRecord(self.list_record(view), grid)

    def stats(self) -> dict:
        s = super().stats()
        s.update(cell=self.cell)
        return s
