"""LBVH traversal: leaves in order of ray entry ``t`` (the paper's Algorithm 1,
the "while-while" loop, as an interval iterator).

At an inner node both children are intersected, the ray descends into the
nearer one and the farther one is set aside with its entry ``t``; a leaf's
interval is yielded; then the next node set aside is taken.

Ordering rule. LBVH node boxes may overlap although bricks do not (two sibling
subtrees' bounding boxes can interleave), so "near child first, pop the stack"
alone does not yield leaves in ray order. The nodes set aside are kept in a
per-ray stack sorted by entry ``t`` (a priority queue by insertion; the far child
pushed while descending usually enters before everything set aside higher up, so
a push rarely moves an entry — measured a few per cent faster than a binary
heap), the top is always the smallest, and the ray only descends into the nearer
child while its entry ``t`` is not larger than the top's. Since a child's box lies
inside its parent's, its entry ``t`` is never smaller than the parent's (also in
floating point: slab distances are monotone in the plane position), so leaves
come out in non-decreasing order of entry ``t``. With the driver's ``k_next``
this takes every lattice sample of the union of the leaves' intervals exactly
once and in increasing ``k``, so leaves need not be disjoint (pruned leaves are
not).

Pruning against ``t_covered`` (the end of the segment the driver holds open): a
node whose interval ends no later than that has nothing left to give (it enters
no earlier than the segment, so its samples are covered already), so it is
neither entered nor taken from the stack. This changes neither the set of
samples nor their order.

Exactness: every sample of non-zero opacity lies in a non-empty brick (apron,
conservative TF range query), every non-empty brick lies in some leaf, and the
driver composites in increasing ``k`` through the naive marcher's own loop. The
nodes set aside (and the current one) never include an ancestor of another, so
the stack never holds more entries than the tree has leaves.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.extending import overload

from ...kernels.borrow import NO_REFCOUNT
from ...kernels.ray import inverse, slab_ordered
from ..interval import make_scratch, next_interval, record_class, start_ray

__all__ = ["LbvhRecord"]


class LbvhRecord(NamedTuple):
    """LBVH arrays (see :mod:`.build`): ``child`` (m, 2) int32, ``box`` (m, 6) float64."""

    SCRATCH = True

    child: np.ndarray
    box: np.ndarray


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
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


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def _node_interval(box, node, ox, oy, oz, ix, iy, iz, fx, fy, fz, sx, sy, sz):
    """Ray interval ``(t_near, t_far)`` in node ``node``'s box (empty: ``t_near > t_far``).

    ``sx, sy, sz``: 0 where the ray goes in +direction on that axis (near plane is
    ``lo``), 3 otherwise; the planes are passed near first, so the arithmetic is
    :func:`~sparsecast.kernels.ray.clip_box`'s without its swap.
    """
    tn, tf = slab_ordered(ox, ix, fx, box[node, sx], box[node, 3 - sx], -math.inf, math.inf)
    tn, tf = slab_ordered(oy, iy, fy, box[node, 1 + sy], box[node, 4 - sy], tn, tf)
    tn, tf = slab_ordered(oz, iz, fz, box[node, 2 + sz], box[node, 5 - sz], tn, tf)
    return tn, tf


@overload(make_scratch, jit_options={"cache": True}, inline="always")
def _scratch(record):
    if record_class(record) is LbvhRecord:

        def impl(record):
            # At most as many entries as leaves, (m + 1) / 2 (module docstring).
            cap = (record.child.shape[0] + 1) // 2 + 1
            return np.empty(cap, np.float64), np.empty(cap, np.float64), np.empty(cap, np.int64)

        return impl


@overload(start_ray, jit_options={"cache": True}, inline="always")
def _start(record, scratch, ray, t_lo, t_hi):
    if record_class(record) is LbvhRecord:

        def impl(record, scratch, ray, t_lo, t_hi):
            ox, oy, oz, dx, dy, dz = ray
            ix, fx = inverse(dx)
            iy, fy = inverse(dy)
            iz, fz = inverse(dz)
            sx = 0 if dx >= 0.0 else 3
            sy = 0 if dy >= 0.0 else 3
            sz = 0 if dz >= 0.0 else 3
            cur = -1
            tn = 0.0
            tf = 0.0
            if record.child.shape[0] > 0:
                tn, tf = _node_interval(record.box, 0, ox, oy, oz, ix, iy, iz, fx, fy, fz, sx, sy, sz)
                if max(tn, 0.0) <= tf:
                    cur = 0
            return (cur, tn, tf, 0, ix, iy, iz, fx, fy, fz, sx, sy, sz)

        return impl


@overload(next_interval, jit_options={"cache": True}, inline="always")
def _next(record, scratch, ray, state, t_covered):
    if record_class(record) is LbvhRecord:

        def impl(record, scratch, ray, state, t_covered):
            cur, cur_tn, cur_tf, hs, ix, iy, iz, fx, fy, fz, sx, sy, sz = state
            ox, oy, oz, dx, dy, dz = ray
            ht, hf, hn = scratch
            child = record.child
            box = record.box
            while cur >= 0 or hs > 0:
                if cur < 0:
                    hs -= 1
                    cur_tn = ht[hs]
                    cur_tf = hf[hs]
                    cur = hn[hs]
                    if cur_tf <= t_covered:
                        cur = -1
                        continue
                c0 = child[cur, 0]
                if c0 < 0:
                    return cur_tn, cur_tf, (-1, cur_tn, cur_tf, hs, ix, iy, iz, fx, fy, fz, sx, sy, sz)
                c1 = child[cur, 1]
                tn0, tf0 = _node_interval(box, c0, ox, oy, oz, ix, iy, iz, fx, fy, fz, sx, sy, sz)
                tn1, tf1 = _node_interval(box, c1, ox, oy, oz, ix, iy, iz, fx, fy, fz, sx, sy, sz)
                hit0 = max(tn0, 0.0) <= tf0 and tf0 > t_covered
                hit1 = max(tn1, 0.0) <= tf1 and tf1 > t_covered
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
            return math.inf, -math.inf, (-1, cur_tn, cur_tf, hs, ix, iy, iz, fx, fy, fz, sx, sy, sz)

        return impl
