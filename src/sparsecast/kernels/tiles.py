"""Screen tiling shared by the parallel renderers."""

from __future__ import annotations

from numba import njit

from .borrow import NO_REFCOUNT


#: Edge of the square pixel tiles the renderers parallelise over. Small tiles
#: balance load on sparse volumes (some tiles are all background), and nearby rays
#: touch the same cache lines.
TILE = 8


@njit(cache=True, **NO_REFCOUNT)
def tile_bounds(tile, width, height):
    """Pixel bounds ``(x0, x1, y0, y1)`` (half-open) of tile number ``tile``."""
    ntx = (width + TILE - 1) // TILE
    ty = tile // ntx
    tx = tile - ty * ntx
    x0 = tx * TILE
    y0 = ty * TILE
    return x0, min(x0 + TILE, width), y0, min(y0 + TILE, height)


@njit(cache=True, **NO_REFCOUNT)
def tile_count(width, height):
    return ((width + TILE - 1) // TILE) * ((height + TILE - 1) // TILE)
