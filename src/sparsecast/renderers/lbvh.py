"""Ray marching with the LBVH over bricks: leaves front to back, lattice samples inside.

Traversal (after the paper's Algorithm 1, the "while-while" loop): at an inner
node both children are intersected, the ray descends into the nearer one and the
farther one is set aside with its entry ``t``; a leaf is marched over its ray
interval with :func:`~sparsecast.kernels.march.march_interval` (global lattice
``t_k = k * dt``, ``k_next`` passed on); then the next node set aside is taken.

Ordering rule. LBVH node boxes may overlap although bricks do not (two sibling
subtrees' bounding boxes can interleave), so "near child first, pop the stack"
alone does not yield leaves in ray order. Here the nodes set aside are kept in a
per-ray stack sorted by entry ``t`` (a priority queue by insertion; the far child
pushed while descending usually enters before everything set aside higher up, so
a push rarely moves an entry — measured a few per cent faster than a binary
heap), the top is always the smallest, and the ray only descends into the nearer
child while its entry ``t`` is not larger than the top's. Since a child's box lies inside its parent's, its entry
``t`` is never smaller than the parent's (also in floating point: slab distances
are monotone in the plane position), so leaves come out in non-decreasing order of
entry ``t``. With ``k_next`` de-duplication this takes every lattice sample of the
union of the leaves' intervals exactly once and in increasing ``k``: a sample of
leaf ``X`` that ``k_next`` skips was taken by an earlier leaf ``P`` (``P`` entered
no later than ``X`` and reached beyond the sample). Leaves therefore need not be
disjoint (pruned leaves are not), and early ray termination simply stops the loop.

Leaves whose interval starts no later than the end of the still unmarched
segment extend that segment (runs of adjacent bricks are marched in one call, as
the grid marcher does with runs of cells), and a node whose interval ends no
later than that segment is skipped (it enters no earlier than the segment, so
its samples are covered already): neither changes the set of samples or their
order.

Exactness: every sample of non-zero opacity lies in a non-empty brick (apron,
conservative TF range query), every non-empty brick lies in some leaf, leaf boxes
lie inside the volume box, and samples are composited in increasing ``k`` through
the same :func:`march_segment` as the naive marcher; hence images equal
``index="naive"`` up to float rounding. The nodes set aside (and the current one)
never include an ancestor of another, so the stack never holds more entries than
the tree has leaves; it is sized so once per tile.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels.camera import index_space_ray
from ..kernels.march import march_interval
from ..kernels.ray import clip_box
from ..kernels.shade import write_pixel
from ..kernels.tiles import tile_bounds, tile_count
from .setup import RenderSetup, register_marcher


@njit(cache=True, inline="always")
def _stack_push(ht, hf, hn, hs, t, tf, node):
    """Insert ``(t, tf, node)`` into the stack of size ``hs``, kept sorted by ``t``
    descending (the top, ``hs - 1``, holds the smallest); returns the new size.

    Far children pushed while descending usually enter before everything set aside
    higher up, so the insertion rarely moves an entry: this is a plain stack push
    in the common case and a priority queue when boxes overlap.
    """
    i = hs
    while i > 0 and ht[i - 1] < t:
        ht[i] = ht[i - 1]
        hf[i] = hf[i - 1]
        hn[i] = hn[i - 1]
        i -= 1
    ht[i] = t
    hf[i] = tf
    hn[i] = node
    return hs + 1


@njit(cache=True, inline="always")
def _stack_pop(ht, hf, hn, hs):
    """Remove the entry with the smallest ``t``; returns ``(t, tf, node, new_size)``."""
    hs -= 1
    return ht[hs], hf[hs], hn[hs], hs


@njit(cache=True, inline="always")
def _slab(o, inv, flat_axis, lo, hi, tn, tf):
    """:func:`kernels.ray.clip_box`'s slab step with ``inv = 1/d`` precomputed per ray.

    ``lo``/``hi`` are the slab planes ordered by the ray's direction (near plane
    first), so no swap is needed; the arithmetic is clip_box's, hence so are the
    results, bit for bit (axis-parallel rays included: ``flat_axis``).
    """
    if flat_axis:
        if o < lo or o > hi:  # d == 0 counts as +direction: lo, hi in order
            return 1.0, 0.0
        return tn, tf
    return max(tn, (lo - o) * inv), min(tf, (hi - o) * inv)


@njit(cache=True, inline="always")
def _node_interval(box, node, ox, oy, oz, ix, iy, iz, fx, fy, fz, sx, sy, sz):
    """Ray interval ``(t_near, t_far)`` in node ``node``'s box (empty: ``t_near > t_far``).

    ``sx, sy, sz``: 0 where the ray goes in +direction on that axis (near plane is
    ``lo``), 3 otherwise.
    """
    tn, tf = _slab(ox, ix, fx, box[node, sx], box[node, 3 - sx], -math.inf, math.inf)
    tn, tf = _slab(oy, iy, fy, box[node, 1 + sy], box[node, 4 - sy], tn, tf)
    tn, tf = _slab(oz, iz, fz, box[node, 2 + sz], box[node, 5 - sz], tn, tf)
    return tn, tf


@njit(cache=True, error_model="numpy")
def lbvh_tile(
    tile, data, child, box,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render the pixels of one 8x8 tile by front-to-back LBVH traversal."""
    nz, ny, nx = data.shape
    flat = data.reshape(nz * ny * nx)
    bx, by, bz = nx - 1.0, ny - 1.0, nz - 1.0
    m = child.shape[0]
    # The per-ray priority stack, allocated once per tile. The nodes it holds (with
    # the current one) never include an ancestor of another, so their subtrees
    # are disjoint and there are at most as many as leaves: (m + 1) / 2.
    cap = (m + 1) // 2 + 1
    ht = np.empty(cap, np.float64)
    hf = np.empty(cap, np.float64)
    hn = np.empty(cap, np.int64)
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
            fx = dx == 0.0
            fy = dy == 0.0
            fz = dz == 0.0
            ix = 1.0 / dx if not fx else 0.0
            iy = 1.0 / dy if not fy else 0.0
            iz = 1.0 / dz if not fz else 0.0
            sx = 0 if dx >= 0.0 else 3
            sy = 0 if dy >= 0.0 else 3
            sz = 0 if dz >= 0.0 else 3
            # The open segment: the union of the leaves taken so far that still
            # has to be marched. Everything up to seg_t1 is taken care of, so a
            # node whose interval ends there has nothing left to give.
            seg_open = False
            seg_t0 = 0.0
            seg_t1 = -math.inf
            cur = -1
            cur_tn = 0.0
            cur_tf = 0.0
            if m > 0:
                t_near, t_far = clip_box(ox, oy, oz, dx, dy, dz, 0.0, 0.0, 0.0, bx, by, bz)
                if max(t_near, 0.0) <= t_far:
                    cur_tn, cur_tf = _node_interval(box, 0, ox, oy, oz, ix, iy, iz, fx, fy, fz, sx, sy, sz)
                    if max(cur_tn, 0.0) <= cur_tf:
                        cur = 0
            hs = 0
            k_next = -(1 << 62)
            while True:
                # Inner loop: descend to the next leaf in order of entry t.
                leaf = False
                while cur >= 0 or hs > 0:
                    if cur < 0:
                        cur_tn, cur_tf, cur, hs = _stack_pop(ht, hf, hn, hs)
                        if cur_tf <= seg_t1:
                            cur = -1
                            continue
                    c0 = child[cur, 0]
                    if c0 < 0:
                        leaf = True
                        break
                    c1 = child[cur, 1]
                    tn0, tf0 = _node_interval(box, c0, ox, oy, oz, ix, iy, iz, fx, fy, fz, sx, sy, sz)
                    tn1, tf1 = _node_interval(box, c1, ox, oy, oz, ix, iy, iz, fx, fy, fz, sx, sy, sz)
                    hit0 = max(tn0, 0.0) <= tf0 and tf0 > seg_t1
                    hit1 = max(tn1, 0.0) <= tf1 and tf1 > seg_t1
                    if hit0 and hit1:
                        # Descend into the nearer child, set the farther aside.
                        if tn1 < tn0:
                            hs = _stack_push(ht, hf, hn, hs, tn0, tf0, c0)
                            cur, cur_tn, cur_tf = c1, tn1, tf1
                        else:
                            hs = _stack_push(ht, hf, hn, hs, tn1, tf1, c1)
                            cur, cur_tn, cur_tf = c0, tn0, tf0
                    elif hit0:
                        cur, cur_tn, cur_tf = c0, tn0, tf0
                    elif hit1:
                        cur, cur_tn, cur_tf = c1, tn1, tf1
                    else:
                        cur = -1
                    # Overlapping boxes: a node set aside may enter earlier.
                    if cur >= 0 and hs > 0 and ht[hs - 1] < cur_tn:
                        hs = _stack_push(ht, hf, hn, hs, cur_tn, cur_tf, cur)
                        cur = -1
                # A leaf touching the open segment extends it: runs of adjacent
                # bricks are marched in one go (the same samples, fewer restarts).
                if leaf and seg_open and cur_tn <= seg_t1:
                    seg_t1 = max(seg_t1, cur_tf)
                    cur = -1
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
                if not leaf:
                    break
                seg_open = True
                seg_t0 = cur_tn
                seg_t1 = cur_tf
                cur = -1
            write_pixel(out_rgba, py, px, r, g, b, a, background)
            out_samples[py, px] = n_samples
            out_nonempty[py, px] = n_nonempty


@njit(cache=True, parallel=True)
def lbvh_kernel(
    data, child, box,
    table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
    background, out_rgba, out_samples, out_nonempty,
):
    """Render every pixel, parallel over 8x8 tiles (see :func:`lbvh_tile`)."""
    for tile in prange(tile_count(width, height)):
        lbvh_tile(
            tile, data, child, box,
            table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, shading,
            background, out_rgba, out_samples, out_nonempty,
        )


@register_marcher("lbvh")
def render_lbvh(index, s: RenderSetup) -> None:
    lbvh_kernel(
        index.volume.data, index.child, index.box,
        s.table, s.v_lo, s.scale, s.cam, s.width, s.height, s.origin, s.inv_spacing, s.dt, s.ert,
        s.shading, s.background, s.rgba, s.samples, s.nonempty,
    )
