"""``grid-mm`` / ``grid-pc``: uniform macrocell grids traversed with a 3-D DDA."""

from .build import CELL_SIZES, MinMaxGrid, PreclassifiedGrid
from .traversal import GridRecord, dda_next, dda_start

__all__ = ["MinMaxGrid", "PreclassifiedGrid", "CELL_SIZES", "GridRecord", "dda_start", "dda_next"]
