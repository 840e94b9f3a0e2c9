"""k-d tree traversal: a per-frame sorted leaf list (shallow) or a per-ray stack (deep).

Exactness. Leaves are disjoint boxes covering every occupied cell, and occupied
cells include a one-cell apron around every cell where a sample can have
non-zero opacity (see :mod:`.build`). Leaves are yielded in a visibility order
(the k-d tree's: near child first, by the eye's side of the split plane, or the
ray direction's sign), so their intervals come front to back. Each interval is
widened by a tiny ``EPS`` (and clipped to the ray's ``[t_lo, t_hi]``) so that
float rounding of the ray/box clip can never drop a sample lying on a face
shared by two leaves; a widened interval only adds lattice samples of the clip
box, in order, which the naive marcher takes too. A ray lying exactly in a split
plane may see the two children's intervals interleave; every sample of non-zero
opacity in that plane lies in both children (its cells on both sides are
occupied), so either order keeps them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.extending import overload

from ...kernels.ray import clip_box
from ..interval import make_scratch, next_interval, record_class, start_ray

__all__ = ["KdListRecord", "KdStackRecord", "EPS", "widen", "next_listed_leaf"]

#: relative widening of every leaf's ray interval (see the module docstring)
EPS = 1e-7


class KdListRecord(NamedTuple):
    """The leaves of a (shallow) k-d tree in front-to-back order for one frame.

    Attributes
    ----------
    order : (nleaves,) int32
        Leaf rows front to back.
    leaf_lo, leaf_hi : (nleaves, 3) float64
        Index-space leaf boxes.
    """

    order: np.ndarray
    leaf_lo: np.ndarray
    leaf_hi: np.ndarray


class KdStackRecord(NamedTuple):
    """A (deep) k-d tree for per-ray stack traversal.

    Attributes
    ----------
    node_axis : (n,) int8
        Split axis, -1 for leaves.
    node_child : (n,) int32
        First child (the second is ``+ 1``).
    node_lo, node_hi : (n, 3) float64
        Index-space node boxes.
    stack_size : int
        Stack entries a ray can need (``2 * height + 4``).
    """

    SCRATCH = True

    node_axis: np.ndarray
    node_child: np.ndarray
    node_lo: np.ndarray
    node_hi: np.ndarray
    stack_size: int


@njit(cache=True, inline="always")
def widen(t_near, t_far, t_lo, t_hi):
    """Leaf interval widened by ``EPS`` (relative to the ray's interval, which is
    finite) and clipped to ``[t_lo, t_hi]``."""
    e = EPS * (1.0 + abs(t_lo) + abs(t_hi))
    return max(t_near - e, t_lo), min(t_far + e, t_hi)


@njit(cache=True, inline="always")
def next_listed_leaf(lst, ray, j, t_lo, t_hi):
    """From position ``j`` of the leaf list, the next leaf the ray meets:
    ``(t0, t1, j_after)``, ``t0 > t1`` when none is left."""
    ox, oy, oz, dx, dy, dz = ray
    order = lst.order
    lo = lst.leaf_lo
    hi = lst.leaf_hi
    while j < order.shape[0]:
        li = order[j]
        j += 1
        tn, tf = clip_box(ox, oy, oz, dx, dy, dz, lo[li, 0], lo[li, 1], lo[li, 2], hi[li, 0], hi[li, 1], hi[li, 2])
        t0, t1 = widen(tn, tf, t_lo, t_hi)
        if t0 <= t1:
            return t0, t1, j
    return math.inf, -math.inf, j


@overload(start_ray, jit_options={"cache": True}, inline="always")
def _start(record, scratch, ray, t_lo, t_hi):
    cls = record_class(record)
    if cls is KdListRecord:
        return lambda record, scratch, ray, t_lo, t_hi: (0, t_lo, t_hi)
    if cls is KdStackRecord:

        def impl(record, scratch, ray, t_lo, t_hi):
            sp = 0
            if record.node_axis.shape[0] > 0:
                scratch[0] = 0
                sp = 1
            return (sp, t_lo, t_hi)

        return impl


@overload(make_scratch, jit_options={"cache": True}, inline="always")
def _scratch(record):
    if record_class(record) is KdStackRecord:
        return lambda record: np.empty(record.stack_size, np.int32)


@overload(next_interval, jit_options={"cache": True}, inline="always")
def _next(record, scratch, ray, state, t_covered):
    cls = record_class(record)
    if cls is KdListRecord:

        def impl_list(record, scratch, ray, state, t_covered):
            j, t_lo, t_hi = state
            t0, t1, j = next_listed_leaf(record, ray, j, t_lo, t_hi)
            return t0, t1, (j, t_lo, t_hi)

        return impl_list
    if cls is KdStackRecord:

        def impl_stack(record, scratch, ray, state, t_covered):
            # A child is pushed only when the ray's widened interval meets it,
            # the near child last (popped first): the left child when the ray's
            # direction on the split axis is >= 0.
            sp, t_lo, t_hi = state
            ox, oy, oz, dx, dy, dz = ray
            lo = record.node_lo
            hi = record.node_hi
            stack = scratch
            while sp > 0:
                sp -= 1
                n = stack[sp]
                tn, tf = clip_box(ox, oy, oz, dx, dy, dz, lo[n, 0], lo[n, 1], lo[n, 2], hi[n, 0], hi[n, 1], hi[n, 2])
                t0, t1 = widen(tn, tf, t_lo, t_hi)
                if t0 > t1:
                    continue
                ax = record.node_axis[n]
                if ax < 0:
                    return t0, t1, (sp, t_lo, t_hi)
                c = record.node_child[n]
                d = dx if ax == 0 else (dy if ax == 1 else dz)
                if d >= 0.0:
                    stack[sp] = c + 1
                    stack[sp + 1] = c
                else:
                    stack[sp] = c
                    stack[sp + 1] = c + 1
                sp += 2
            return math.inf, -math.inf, (sp, t_lo, t_hi)

        return impl_stack
