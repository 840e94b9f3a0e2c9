"""The naive (reference) ray marcher: every lattice sample inside the volume box."""

from __future__ import annotations

from numba import njit, prange

from ..kernels.camera import index_space_ray
from ..kernels.march import march_segment
from ..kernels.ray import clip_box, lattice_range
from ..kernels.shade import write_pixel
from ..kernels.tiles import tile_bounds, tile_count
from .setup import RenderSetup, register_marcher


@njit(cache=True, error_model="numpy")
def naive_tile(
    tile, data, table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render the pixels of one 8x8 tile."""
    nz, ny, nx = data.shape
    flat = data.reshape(nz * ny * nx)  # a view of the C-contiguous voxels
    bx, by, bz = nx - 1.0, ny - 1.0, nz - 1.0
    x0, x1, y0, y1 = tile_bounds(tile, width, height)
    for py in range(y0, y1):
        for px in range(x0, x1):
            ox, oy, oz, dx, dy, dz, wdx, wdy, wdz = index_space_ray(
                cam, px, py, width, height, origin, inv_spacing
            )
            t_near, t_far = clip_box(ox, oy, oz, dx, dy, dz, 0.0, 0.0, 0.0, bx, by, bz)
            k0, k1 = lattice_range(t_near, t_far, dt)
            r, g, b, a, _, ns, nne = march_segment(
                flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz, wdx, wdy, wdz,
                inv_spacing, dt, k0, k1, 0.0, 0.0, 0.0, 0.0, ert, shading,
            )
            write_pixel(out_rgba, py, px, r, g, b, a, background)
            out_samples[py, px] = ns
            out_nonempty[py, px] = nne


@njit(cache=True, parallel=True)
def naive_kernel(
    data, table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render every pixel, parallel over 8x8 tiles.

    The tile body lives in its own (serial) function on purpose: Numba optimises
    it as ordinary code, which ran about 1.5x faster than the same loops written
    inside the ``prange`` body, and it compiles faster too.
    """
    for tile in prange(tile_count(width, height)):
        naive_tile(
            tile, data, table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert,
            shading, background, out_rgba, out_samples, out_nonempty,
        )


@register_marcher("naive")
def render_naive(index, s: RenderSetup) -> None:
    naive_kernel(
        index.volume.data, s.table, s.v_lo, s.scale, s.cam, s.width, s.height, s.origin,
        s.inv_spacing, s.dt, s.ert, s.shading, s.background, s.rgba, s.samples, s.nonempty,
    )
