"""Ray marching with k-d trees: a per-frame sorted leaf list (shallow) or a per-ray
stack traversal (deep).

Exactness. Leaves are disjoint boxes covering every occupied cell, and occupied
cells include a one-cell apron around every cell where a sample can have
non-zero opacity (see :mod:`sparsecast.index.kdtree`). Leaves are visited in a
visibility order (the k-d tree's: near child first, by the eye's side of the
split plane, or the ray direction's sign), and each leaf's ray interval is
marched with :func:`~sparsecast.kernels.march.march_interval` on the global
lattice with ``k_next`` carried over, so samples are taken in increasing ``k``
and at most once. Each interval is widened by a tiny ``eps`` (and clipped to the
volume's interval) so that float rounding of the ray/box clip can never drop a
sample lying on a face shared by two leaves; a widened interval only adds
lattice samples of the volume box, in order, which the naive marcher takes too.
A ray lying exactly in a split plane may see the two children's intervals
interleave; every sample of non-zero opacity in that plane lies in both
children (its cells on both sides are occupied), so either order keeps them.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..kernels.camera import index_space_ray
from ..kernels.march import march_interval
from ..kernels.ray import clip_box
from ..kernels.shade import write_pixel
from ..kernels.tiles import tile_bounds, tile_count
from .setup import RenderSetup, register_marcher

#: relative widening of every leaf's ray interval (see the module docstring)
EPS = 1e-7


@njit(cache=True, inline="always")
def _widen(t_near, t_far, t_lo, t_hi):
    """Leaf interval widened by ``EPS`` (relative to the volume's interval, which is
    finite) and clipped to the volume's ``[t_lo, t_hi]``."""
    e = EPS * (1.0 + abs(t_lo) + abs(t_hi))
    return max(t_near - e, t_lo), min(t_far + e, t_hi)


@njit(cache=True, error_model="numpy")
def kd_list_tile(
    tile, data, order, leaf_lo, leaf_hi,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render one 8x8 tile: every ray intersects the front-to-back leaf list ``order``."""
    nz, ny, nx = data.shape
    flat = data.reshape(nz * ny * nx)
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
                    r, g, b, a, k_next, ns, nne = march_interval(
                        flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
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
def kd_list_kernel(
    data, order, leaf_lo, leaf_hi,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render every pixel, parallel over 8x8 tiles (see :func:`kd_list_tile`)."""
    for tile in prange(tile_count(width, height)):
        kd_list_tile(
            tile, data, order, leaf_lo, leaf_hi,
            table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
            background, out_rgba, out_samples, out_nonempty,
        )


@njit(cache=True, error_model="numpy")
def kd_stack_tile(
    tile, data, node_axis, node_child, node_lo, node_hi, stack_size,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render one 8x8 tile with a per-ray stack traversal of the tree.

    ``node_lo/node_hi`` are the index-space boxes of all nodes; a child is pushed
    only when the ray's widened interval meets it, the near child last (popped
    first): the left child when the ray's direction on the split axis is >= 0.
    """
    nz, ny, nx = data.shape
    flat = data.reshape(nz * ny * nx)
    bx, by, bz = nx - 1.0, ny - 1.0, nz - 1.0
    stack = np.empty(stack_size, np.int32)
    x0, x1, y0, y1 = tile_bounds(tile, width, height)
    n_nodes = node_axis.shape[0]
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
            if t_lo <= t_far and n_nodes > 0:
                k_next = -(1 << 62)
                sp = 0
                stack[0] = 0
                sp = 1
                while sp > 0:
                    sp -= 1
                    n = stack[sp]
                    tn, tf = clip_box(ox, oy, oz, dx, dy, dz, node_lo[n, 0], node_lo[n, 1], node_lo[n, 2],
                                      node_hi[n, 0], node_hi[n, 1], node_hi[n, 2])
                    t0, t1 = _widen(tn, tf, t_lo, t_far)
                    if t0 > t1:
                        continue
                    ax = node_axis[n]
                    if ax < 0:
                        r, g, b, a, k_next, ns, nne = march_interval(
                            flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
                            wdx, wdy, wdz, inv_spacing, dt, t0, t1, k_next, r, g, b, a, ert, shading,
                        )
                        n_samples += ns
                        n_nonempty += nne
                        if a >= ert:
                            break
                        continue
                    c = node_child[n]
                    if ax == 0:
                        d = dx
                    elif ax == 1:
                        d = dy
                    else:
                        d = dz
                    if d >= 0.0:
                        stack[sp] = c + 1
                        stack[sp + 1] = c
                    else:
                        stack[sp] = c
                        stack[sp + 1] = c + 1
                    sp += 2
            write_pixel(out_rgba, py, px, r, g, b, a, background)
            out_samples[py, px] = n_samples
            out_nonempty[py, px] = n_nonempty


@njit(cache=True, parallel=True)
def kd_stack_kernel(
    data, node_axis, node_child, node_lo, node_hi, stack_size,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render every pixel, parallel over 8x8 tiles (see :func:`kd_stack_tile`)."""
    for tile in prange(tile_count(width, height)):
        kd_stack_tile(
            tile, data, node_axis, node_child, node_lo, node_hi, stack_size,
            table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
            background, out_rgba, out_samples, out_nonempty,
        )


def frame_leaf_order(index, s: RenderSetup) -> np.ndarray:
    """The leaves front to back for this frame's camera (CPU, once per frame)."""
    cam = s.cam
    perspective = cam[12] != 0.0
    if perspective:
        key = (cam[0:3] - s.origin) * s.inv_spacing  # eye in index space
    else:
        key = cam[3:6] * s.inv_spacing  # view direction in index space (same signs)
    return index.leaf_order(key, perspective)


def node_index_boxes(index) -> tuple[np.ndarray, np.ndarray]:
    """Index-space boxes of all nodes (cached on the index)."""
    cached = getattr(index, "_node_index_boxes", None)
    if cached is None:
        nz, ny, nx = index.volume.shape
        top = np.array([nx - 1, ny - 1, nz - 1], np.float64)
        b = index.node_box.astype(np.float64)
        cached = (np.ascontiguousarray(np.minimum(b[:, 0:3], top)),
                  np.ascontiguousarray(np.minimum(b[:, 3:6], top)))
        index._node_index_boxes = cached
    return cached


@register_marcher("kdtree-shallow")
def render_kdtree_shallow(index, s: RenderSetup) -> None:
    order = frame_leaf_order(index, s)
    kd_list_kernel(
        index.volume.data, order, index.leaf_lo, index.leaf_hi,
        s.table, s.v_lo, s.scale, s.cam, s.width, s.height, s.origin, s.inv_spacing, s.dt, s.ert,
        s.shading, s.background, s.rgba, s.samples, s.nonempty,
    )


@register_marcher("kdtree-deep")
def render_kdtree_deep(index, s: RenderSetup) -> None:
    node_lo, node_hi = node_index_boxes(index)
    stack_size = 2 * max(index.height, 1) + 4
    kd_stack_kernel(
        index.volume.data, index.node_axis, index.node_child, node_lo, node_hi, stack_size,
        s.table, s.v_lo, s.scale, s.cam, s.width, s.height, s.origin, s.inv_spacing, s.dt, s.ert,
        s.shading, s.background, s.rgba, s.samples, s.nonempty,
    )
