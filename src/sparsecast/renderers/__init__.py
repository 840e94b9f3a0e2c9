"""Renderers: the DVR entry point and one marcher per index."""

from . import grid as _grid  # noqa: F401  (registers grid-mm, grid-pc)
from . import naive as _naive  # noqa: F401  (registers the naive marcher)
from . import hybrid as _hybrid, kdtree as _kdtree  # noqa: F401  (k-d tree and hybrid-grid marchers)
from . import lbvh as _lbvh  # noqa: F401  (registers the lbvh marcher)
from . import bih as _bih  # noqa: F401  (registers the bih marcher)
from .dvr import DEFAULT_SHADING, render
from .image import Image

__all__ = ["render", "Image", "DEFAULT_SHADING"]
