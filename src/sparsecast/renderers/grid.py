"""Ray marching with a macrocell grid: DDA over cells, lattice samples in non-empty ones.

Exactness: inside a non-empty cell the marcher visits the *global* lattice indices
``k`` whose ``t_k = k * dt`` falls in the cell's ray interval, through the same
:func:`~sparsecast.kernels.march.march_segment` as the naive marcher; consecutive
cells share their boundary parameter, and runs of consecutive non-empty cells
are marched as one segment, so no sample is taken twice or missed between cells. A sample that rounding attributes to a
neighbouring cell is within one voxel of it, which the cells' one-voxel apron
covers, so skipping a cell classified empty never drops a sample of non-zero
opacity. Hence images equal ``index="naive"`` up to float rounding.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..kernels.camera import index_space_ray
from ..kernels.dda import dda_march
from ..kernels.ray import clip_box
from ..kernels.shade import write_pixel
from ..kernels.tiles import tile_bounds, tile_count
from .setup import RenderSetup, register_marcher

_NO_MASK = np.zeros((1, 1, 1), np.uint8)


@njit(cache=True, error_model="numpy")
def grid_tile(
    tile, data, cell, occupied, cell_min, cell_max, use_minmax, prefix,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render the pixels of one 8x8 tile with DDA cell skipping.

    ``use_minmax`` selects how a cell is classified: from its ``[cell_min, cell_max]``
    and the TF ``prefix`` counts (min-max grid), or from ``occupied`` (pre-classified).
    """
    nz, ny, nx = data.shape
    flat = data.reshape(nz * ny * nx)
    ncz, ncy, ncx = cell_min.shape
    bx, by, bz = nx - 1.0, ny - 1.0, nz - 1.0
    x0, x1, y0, y1 = tile_bounds(tile, width, height)
    for py in range(y0, y1):
        for px in range(x0, x1):
            ox, oy, oz, dx, dy, dz, wdx, wdy, wdz = index_space_ray(
                cam, px, py, width, height, origin, inv_spacing
            )
            t_near, t_far = clip_box(ox, oy, oz, dx, dy, dz, 0.0, 0.0, 0.0, bx, by, bz)
            r = 0.0
            g = 0.0
            b = 0.0
            a = 0.0
            n_samples = 0
            n_nonempty = 0
            t_enter = max(t_near, 0.0)
            if t_enter <= t_far:
                r, g, b, a, _, n_samples, n_nonempty = dda_march(
                    flat, nx, ny, nz, cell, ncx, ncy, ncz, occupied, cell_min, cell_max,
                    use_minmax, prefix, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
                    wdx, wdy, wdz, inv_spacing, dt, t_enter, t_far, -(1 << 62), r, g, b, a,
                    ert, shading,
                )
            write_pixel(out_rgba, py, px, r, g, b, a, background)
            out_samples[py, px] = n_samples
            out_nonempty[py, px] = n_nonempty


@njit(cache=True, parallel=True)
def grid_kernel(
    data, cell, occupied, cell_min, cell_max, use_minmax, prefix,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render every pixel, parallel over 8x8 tiles (see :func:`grid_tile`)."""
    for tile in prange(tile_count(width, height)):
        grid_tile(
            tile, data, cell, occupied, cell_min, cell_max, use_minmax, prefix,
            table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
            background, out_rgba, out_samples, out_nonempty,
        )


def _render_grid(index, s: RenderSetup, use_minmax: bool) -> None:
    occupied = _NO_MASK if use_minmax else index.occupied
    grid_kernel(
        index.volume.data, float(index.cell), occupied, index.cell_min, index.cell_max,
        use_minmax, index.tf.prefix, s.table, s.v_lo, s.scale, s.cam, s.width, s.height,
        s.origin, s.inv_spacing, s.dt, s.ert, s.shading, s.background, s.rgba, s.samples,
        s.nonempty,
    )


@register_marcher("grid-mm")
def render_grid_mm(index, s: RenderSetup) -> None:
    _render_grid(index, s, use_minmax=True)


@register_marcher("grid-pc")
def render_grid_pc(index, s: RenderSetup) -> None:
    _render_grid(index, s, use_minmax=False)
