"""``kdtree-shallow`` / ``kdtree-deep``: k-d trees built with partial summed-volume tables."""

from .build import CellOccupancy, DeepKdTree, KdTree, ShallowKdTree, cell_occupancy
from .traversal import KdListRecord, KdStackRecord

__all__ = ["KdTree", "ShallowKdTree", "DeepKdTree", "CellOccupancy", "cell_occupancy",
           "KdListRecord", "KdStackRecord"]
