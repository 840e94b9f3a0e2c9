"""Spatial indices for empty-space skipping, one package each.

Each package owns its build (``build.py`` and its kernels) and its traversal
(``traversal.py``: a record type with the interval-iterator overloads of
:mod:`.interval`). Importing this package registers every index;
``build_index(volume, tf, name)`` builds one by name.
"""

from .base import SpatialIndex, View
from .registry import available_indices, build_index, index_options, parse_index_spec, register_index
from . import naive as _naive  # noqa: F401  (registers "naive")
from . import grid as _grid  # noqa: F401  (registers "grid-mm", "grid-pc")
from . import kdtree as _kdtree  # noqa: F401  (kdtree-shallow/-deep)
from . import hybrid as _hybrid  # noqa: F401  (hybrid-pc/-mm)
from . import lbvh as _lbvh  # noqa: F401  (registers "lbvh")
from . import bih as _bih  # noqa: F401  (registers "bih")

__all__ = ["SpatialIndex", "View", "available_indices", "build_index", "index_options", "parse_index_spec",
           "register_index"]
