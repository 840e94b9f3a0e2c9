"""Uniform macrocell grids: min-max (``grid-mm``) and pre-classified (``grid-pc``).

The volume's domain is cut into cells of ``cell`` x ``cell`` x ``cell`` voxel cells
(cell ``c`` spans index coordinates ``[c*C, (c+1)*C]`` on each axis, clipped to
the domain). Each cell's value range includes a one-voxel apron, so it bounds
every trilinear sample inside the cell; a renderer walks the cells along each ray
with a 3-D DDA (Amanatides & Woo 1987) and samples only non-empty ones.

``grid-mm`` keeps the per-cell ``[min, max]`` and asks the transfer function at
render time (O(1) prefix-count query per visited cell): nothing to rebuild when
the TF changes. ``grid-pc`` bakes the answer into one byte per cell when the
index is built: a TF change costs one pass over the cells, none over voxels.

Both derive cell ranges from the volume's cached brick statistics
(:meth:`Volume.brick_stats`), so after the first build on a volume, building
again for another TF touches no voxels.
"""

from __future__ import annotations

import time

import numpy as np

from ..._util.checks import as_int, one_of
from ..base import SpatialIndex, View
from ..registry import register_index
from .traversal import GridRecord

__all__ = ["MinMaxGrid", "PreclassifiedGrid"]

#: stands in for the arrays a grid kind does not read (one record type for both kinds)
_NO_MASK = np.zeros((1, 1, 1), np.uint8)

#: cell sizes accepted (voxels per cell edge)
CELL_SIZES = (4, 8, 16, 32, 64)


def _check_cell(cell) -> int:
    expected = f"one of {CELL_SIZES} voxels"
    return one_of(as_int(cell, "cell", expected=expected), "cell", CELL_SIZES, expected=expected)


class _CellGrid(SpatialIndex):
    """Shared part: cell size and per-cell value ranges.

    Arrays (traversed by :mod:`.traversal`)
    ---------------------------------------
    cell_min, cell_max : (ncz, ncy, ncx) float64
        Value range of each cell including the one-voxel apron.
    cell : int
        Voxels per cell edge.
    """

    def __init__(self, volume, tf, cell: int = 16) -> None:
        super().__init__(volume, tf)
        self.cell = _check_cell(cell)
        t0 = time.perf_counter()
        stats = volume.brick_stats(self.cell)  # cached per volume after the first build
        self.cell_min = stats.vmin
        self.cell_max = stats.vmax
        self.build_phases["cell_ranges"] = (time.perf_counter() - t0) * 1e3

    @property
    def shape(self) -> tuple[int, int, int]:
        """Cell counts ``(ncz, ncy, ncx)``."""
        return self.cell_min.shape  # type: ignore[return-value]

    def occupancy(self) -> float:
        """Fraction of cells that are non-empty for this index's TF."""
        return float(self.tf.classify(self.cell_min, self.cell_max).mean())

    def stats(self) -> dict:
        s = super().stats()
        s.update(cell=self.cell, cells=int(np.prod(self.shape)), occupancy=self.occupancy())
        return s

    def grid_record(self, use_minmax: bool) -> GridRecord:
        """The grid as the DDA reads it (also used inside hybrid-grid leaves)."""
        ncz, ncy, ncx = self.shape
        return GridRecord(
            cell=float(self.cell), use_minmax=use_minmax,
            occupied=_NO_MASK if use_minmax else self.occupied,
            cell_min=self.cell_min, cell_max=self.cell_max, prefix=self.tf.prefix,
            v_lo=float(self.tf.value_range[0]), scale=float(self.tf.scale), ncx=ncx, ncy=ncy, ncz=ncz,
        )


@register_index
class MinMaxGrid(_CellGrid):
    """Min-max macrocell grid: cells classified on the fly during traversal.

    Parameters
    ----------
    volume, tf
        What to index.
    cell : int
        Voxels per cell edge, one of 4, 8, 16 (default), 32, 64.
    """

    name = "grid-mm"

    def __init__(self, volume, tf, cell: int = 16) -> None:
        super().__init__(volume, tf, cell)
        self.nbytes = int(self.cell_min.nbytes + self.cell_max.nbytes)

    def traversal_record(self, view: View) -> GridRecord:
        return self.grid_record(use_minmax=True)


@register_index
class PreclassifiedGrid(_CellGrid):
    """Pre-classified macrocell grid: one occupancy byte per cell, rebuilt per TF.

    Parameters
    ----------
    volume, tf
        What to index.
    cell : int
        Voxels per cell edge, one of 4, 8, 16 (default), 32, 64.

    Attributes
    ----------
    occupied : (ncz, ncy, ncx) uint8
        1 where the cell has any sample of non-zero opacity.
    """

    name = "grid-pc"

    def __init__(self, volume, tf, cell: int = 16) -> None:
        super().__init__(volume, tf, cell)
        t0 = time.perf_counter()
        self.occupied = tf.classify_bricks(volume, self.cell).astype(np.uint8)
        self.build_phases["classify"] = (time.perf_counter() - t0) * 1e3
        self.nbytes = int(self.occupied.nbytes)

    def occupancy(self) -> float:
        return float(self.occupied.mean())

    def traversal_record(self, view: View) -> GridRecord:
        return self.grid_record(use_minmax=False)
