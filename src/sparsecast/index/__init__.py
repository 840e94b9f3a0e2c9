"""Spatial indices for empty-space skipping, one module each.

Importing this package registers every index; ``build_index(volume, tf, name)``
builds one by name.
"""

from .base import SpatialIndex
from .registry import available_indices, build_index, register_index
from . import grid as _grid  # noqa: F401  (registers "grid-mm", "grid-pc")
from . import naive as _naive  # noqa: F401  (registers "naive")
from . import hybrid as _hybrid, kdtree as _kdtree  # noqa: F401  (kdtree-shallow/-deep, hybrid-pc/-mm)
from . import lbvh as _lbvh  # noqa: F401  (registers "lbvh")
from . import bih as _bih  # noqa: F401  (registers "bih")

__all__ = ["SpatialIndex", "available_indices", "build_index", "register_index"]
