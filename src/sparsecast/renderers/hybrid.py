"""Ray marching with hybrid grids: shallow k-d tree leaves front to back, and inside
each leaf a DDA over the 16^3 macrocell grid that marches non-empty cells only.

Exactness combines the two arguments: the leaf list is visited as in
:mod:`.kdtree` (widened, clipped intervals with ``k_next`` carried over), and
inside a leaf's interval the DDA classifies exactly as the grid marcher
(:mod:`.grid`) does over a whole ray, whose cells' one-voxel apron covers a
sample that rounding attributes to a neighbouring cell.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..kernels.camera import index_space_ray
from ..kernels.dda import dda_march
from ..kernels.ray import clip_box
from ..kernels.shade import write_pixel
from ..kernels.tiles import tile_bounds, tile_count
from .kdtree import _widen, frame_leaf_order
from .setup import RenderSetup, register_marcher

_NO_MASK = np.zeros((1, 1, 1), np.uint8)
_NO_RANGE = np.zeros((1, 1, 1), np.float64)


@njit(cache=True, error_model="numpy")
def hybrid_tile(
    tile, data, order, leaf_lo, leaf_hi, cell, occupied, cell_min, cell_max, use_minmax, prefix,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render one 8x8 tile: sorted leaves, DDA over the grid inside each."""
    nz, ny, nx = data.shape
    flat = data.reshape(nz * ny * nx)
    if use_minmax:
        ncz, ncy, ncx = cell_min.shape
    else:
        ncz, ncy, ncx = occupied.shape
    bx, by, bz = nx - 1.0, ny - 1.0, nz - 1.0
    x0, x1, y0, y1 = tile_bounds(tile, width, height)
    for py in range(y0, y1):
        for px in range(x0, x1):
            ox, oy, oz, dx, dy, dz, wdx, wdy, wdz = index_space_ray(
                cam, px, py, width, height, origin, inv_spacing
            )
            t_near, t_far = clip_box(ox, oy, oz, dx, dy, dz, 0.0, 0.0, 0.0, bx, by, bz)
            t_lo = max(t_near, 0.0)
            r = 0.0
            g = 0.0
            b = 0.0
            a = 0.0
            n_samples = 0
            n_nonempty = 0
            if t_lo <= t_far:
                k_next = -(1 << 62)
                for j in range(order.shape[0]):
                    li = order[j]
                    tn, tf = clip_box(ox, oy, oz, dx, dy, dz, leaf_lo[li, 0], leaf_lo[li, 1], leaf_lo[li, 2],
                                      leaf_hi[li, 0], leaf_hi[li, 1], leaf_hi[li, 2])
                    t0, t1 = _widen(tn, tf, t_lo, t_far)
                    if t0 > t1:
                        continue
                    r, g, b, a, k_next, ns, nne = dda_march(
                        flat, nx, ny, nz, cell, ncx, ncy, ncz, occupied, cell_min, cell_max,
                        use_minmax, prefix, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
                        wdx, wdy, wdz, inv_spacing, dt, t0, t1, k_next, r, g, b, a, ert, shading,
                    )
                    n_samples += ns
                    n_nonempty += nne
                    if a >= ert:
                        break
            write_pixel(out_rgba, py, px, r, g, b, a, background)
            out_samples[py, px] = n_samples
            out_nonempty[py, px] = n_nonempty


@njit(cache=True, parallel=True)
def hybrid_kernel(
    data, order, leaf_lo, leaf_hi, cell, occupied, cell_min, cell_max, use_minmax, prefix,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render every pixel, parallel over 8x8 tiles (see :func:`hybrid_tile`)."""
    for tile in prange(tile_count(width, height)):
        hybrid_tile(
            tile, data, order, leaf_lo, leaf_hi, cell, occupied, cell_min, cell_max, use_minmax,
            prefix, table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
            background, out_rgba, out_samples, out_nonempty,
        )


def _render_hybrid(index, s: RenderSetup, use_minmax: bool) -> None:
    order = frame_leaf_order(index, s)
    occupied = _NO_MASK if use_minmax else index.occupied
    cell_min = index.cell_min if use_minmax else _NO_RANGE
    cell_max = index.cell_max if use_minmax else _NO_RANGE
    hybrid_kernel(
        index.volume.data, order, index.leaf_lo, index.leaf_hi, float(index.cell), occupied,
        cell_min, cell_max, use_minmax, index.tf.prefix,
        s.table, s.v_lo, s.scale, s.cam, s.width, s.height, s.origin, s.inv_spacing, s.dt, s.ert,
        s.shading, s.background, s.rgba, s.samples, s.nonempty,
    )


@register_marcher("hybrid-pc")
def render_hybrid_pc(index, s: RenderSetup) -> None:
    _render_hybrid(index, s, use_minmax=False)


@register_marcher("hybrid-mm")
def render_hybrid_mm(index, s: RenderSetup) -> None:
    _render_hybrid(index, s, use_minmax=True)
