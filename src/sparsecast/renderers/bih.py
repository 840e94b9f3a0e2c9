"""Ray casting with a packed BIH: ``render(..., index="bih", mode=...)``.

Every mode walks the packed nodes front to back with
:func:`sparsecast.index._bih_traversal.next_leaf` from the ray's interval in the
volume box (rays are clipped to the box, as the naive marcher's are) and stops at
early ray termination.

``ess``            leaves are (merged) non-empty bricks whose planes are exact in
                   the packed frame, so leaves are disjoint and come out in order of
                   entry ``t``; runs of touching leaves are marched as one segment
                   with :func:`~sparsecast.kernels.march.march_interval`, passing
                   ``k_next`` on: every lattice sample in a non-empty brick is taken
                   once, in increasing ``k``, through the naive marcher's own
                   :func:`march_segment` -- the naive image up to float rounding.
``single-sample``  one sample per leaf segment ``[t0, t1]`` at its midpoint, density
                   ``d(x) = d_c + g . (x - c)`` (``c`` the leaf box centre, ``g`` the
                   leaf's mean gradient per voxel), opacity corrected for the segment
                   length: ``a' = 1 - (1 - a_dt) ** ((t1 - t0) / dt)`` with ``a_dt`` the
                   step-corrected table entry, i.e. ``1 - (1 - a) ** (l / unit)``.
``multi-sample``   the global lattice samples inside each leaf with that density.

Between leaves (below the element threshold) the approximate modes see nothing.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..index._bih_kernels import DENSITY_MAX, GRAD_MAX, GRAD_ZERO
from ..index._bih_traversal import next_leaf, push_root, set_ray, traversal_arrays
from ..kernels.camera import index_space_ray
from ..kernels.march import march_interval
from ..kernels.ray import clip_box, lattice_range
from ..kernels.shade import SHADING_ENABLED, blinn_phong, tf_alpha, tf_color, write_pixel
from ..kernels.tiles import tile_bounds, tile_count
from .setup import RenderSetup, register_marcher

MODE_ESS, MODE_SINGLE, MODE_MULTI = 0, 1, 2
_MODES = {"ess": MODE_ESS, "single-sample": MODE_SINGLE, "multi-sample": MODE_MULTI}


@njit(cache=True, inline="always")
def leaf_payload(nodes, leaf, grad_scale):
    """Density in [0, 1] and gradient of a packed volume leaf."""
    w = nodes[leaf]
    d = ((w >> 48) & 0x3FFF) / DENSITY_MAX
    s = grad_scale / GRAD_MAX
    gx = ((w & 0xFFFF) - GRAD_ZERO) * s
    gy = (((w >> 16) & 0xFFFF) - GRAD_ZERO) * s
    gz = (((w >> 32) & 0xFFFF) - GRAD_ZERO) * s
    return d, gx, gy, gz


@njit(cache=True)
def _composite(table, v, v_lo, scale, seg_steps, gx, gy, gz, wdx, wdy, wdz, inv_spacing, shading,
               r, g, b, a):
    """Composite one approximated sample of value ``v`` standing for ``seg_steps``
    lattice steps (1 for a lattice sample); returns the accumulation and whether
    its opacity was non-zero."""
    i, f, alpha = tf_alpha(table, v, v_lo, scale)
    if alpha <= 0.0:
        return r, g, b, a, False
    if seg_steps != 1.0:
        alpha = 1.0 - (1.0 - min(alpha, 1.0)) ** seg_steps
    cr, cg, cb = tf_color(table, i, f)
    if shading[SHADING_ENABLED] != 0.0:
        cr, cg, cb = blinn_phong(cr, cg, cb, gx * inv_spacing[0], gy * inv_spacing[1], gz * inv_spacing[2],
                                 wdx, wdy, wdz, shading)
    w = (1.0 - a) * alpha
    return r + w * cr, g + w * cg, b + w * cb, a + w, True


@njit(cache=True, error_model="numpy")
def bih_tile(
    tile, mode, data, nodes, preorder, frame_lo, frame_step, root_box, depth, grad_scale, d_lo, d_span,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render the pixels of one 8x8 tile by front-to-back BIH traversal."""
    nz, ny, nx = data.shape
    flat = data.reshape(nz * ny * nx)
    bx, by, bz = nx - 1.0, ny - 1.0, nz - 1.0
    st_node, st_t, st_box, leaf_box, ro, rinv, rflat = traversal_arrays(depth)
    has_nodes = nodes.shape[0] > 0
    x0, x1, y0, y1 = tile_bounds(tile, width, height)
    for py in range(y0, y1):
        for px in range(x0, x1):
            ox, oy, oz, dx, dy, dz, wdx, wdy, wdz = index_space_ray(
                cam, px, py, width, height, origin, inv_spacing
            )
            r = 0.0
            g = 0.0
            b = 0.0
            a = 0.0
            n_samples = 0
            n_nonempty = 0
            hs = 0
            if has_nodes:
                t_near, t_far = clip_box(ox, oy, oz, dx, dy, dz, 0.0, 0.0, 0.0, bx, by, bz)
                if max(t_near, 0.0) <= t_far:
                    set_ray(ro, rinv, rflat, ox, oy, oz, dx, dy, dz)
                    hs = push_root(root_box, ro, rinv, rflat, max(t_near, 0.0), t_far, st_node, st_t, st_box)
            k_next = -(1 << 62)
            seg_open = False
            seg_t0 = 0.0
            seg_t1 = 0.0
            while True:
                leaf, t0, t1, hs = next_leaf(nodes, preorder, frame_lo, frame_step, 0.0, ro, rinv, rflat,
                                             st_node, st_t, st_box, hs, leaf_box)
                if mode == MODE_ESS:
                    # Touching leaves extend the open segment (one march per run).
                    if leaf >= 0 and seg_open and t0 <= seg_t1:
                        seg_t1 = max(seg_t1, t1)
                        continue
                    if seg_open:
                        r, g, b, a, k_next, ns, nne = march_interval(
                            flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
                            wdx, wdy, wdz, inv_spacing, dt, seg_t0, seg_t1,
                            k_next, r, g, b, a, ert, shading,
                        )
                        n_samples += ns
                        n_nonempty += nne
                        if a >= ert:
                            break
                    if leaf < 0:
                        break
                    seg_open = True
                    seg_t0 = t0
                    seg_t1 = t1
                    continue
                if leaf < 0:
                    break
                dc, gx, gy, gz = leaf_payload(nodes, leaf, grad_scale)
                cx = 0.5 * (leaf_box[0] + leaf_box[3])
                cy = 0.5 * (leaf_box[1] + leaf_box[4])
                cz = 0.5 * (leaf_box[2] + leaf_box[5])
                if mode == MODE_SINGLE:
                    if t1 <= t0:
                        continue
                    tm = 0.5 * (t0 + t1)
                    d = dc + gx * (ox + tm * dx - cx) + gy * (oy + tm * dy - cy) + gz * (oz + tm * dz - cz)
                    r, g, b, a, hit = _composite(table, d_lo + d * d_span, v_lo, scale, (t1 - t0) / dt,
                                                 gx, gy, gz, wdx, wdy, wdz, inv_spacing, shading, r, g, b, a)
                    n_samples += 1
                    n_nonempty += hit
                else:
                    k0, k1 = lattice_range(t0, t1, dt)
                    k = max(k0, k_next)
                    while k <= k1 and a < ert:
                        t = k * dt
                        d = dc + gx * (ox + t * dx - cx) + gy * (oy + t * dy - cy) + gz * (oz + t * dz - cz)
                        r, g, b, a, hit = _composite(table, d_lo + d * d_span, v_lo, scale, 1.0,
                                                     gx, gy, gz, wdx, wdy, wdz, inv_spacing, shading,
                                                     r, g, b, a)
                        n_samples += 1
                        n_nonempty += hit
                        k += 1
                    k_next = max(k_next, k)
                if a >= ert:
                    break
            write_pixel(out_rgba, py, px, r, g, b, a, background)
            out_samples[py, px] = n_samples
            out_nonempty[py, px] = n_nonempty


@njit(cache=True, parallel=True)
def bih_kernel(
    mode, data, nodes, preorder, frame_lo, frame_step, root_box, depth, grad_scale, d_lo, d_span,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render every pixel, parallel over 8x8 tiles (see :func:`bih_tile`)."""
    for tile in prange(tile_count(width, height)):
        bih_tile(
            tile, mode, data, nodes, preorder, frame_lo, frame_step, root_box, depth, grad_scale, d_lo, d_span,
            table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
            background, out_rgba, out_samples, out_nonempty,
        )


@register_marcher("bih")
def render_bih(index, s: RenderSetup) -> None:
    p = index.packed
    bih_kernel(
        _MODES[index.mode], index.volume.data, p.words, p.preorder, p.frame_lo, p.frame_step, p.root_box,
        p.depth, p.grad_scale, index.v_lo, index.v_span,
        s.table, s.v_lo, s.scale, s.cam, s.width, s.height, s.origin, s.inv_spacing, s.dt, s.ert,
        s.shading, s.background, s.rgba, s.samples, s.nonempty,
    )


__all__ = ["render_bih", "bih_kernel", "leaf_payload", "MODE_ESS", "MODE_SINGLE", "MODE_MULTI"]
