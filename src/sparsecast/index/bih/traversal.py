"""Ordered traversal of a packed BIH (Kinkelin's Algorithms 1 and 2), read straight
from the 64-bit node words of :class:`sparsecast.index.bih.PackedBIH`.

A ray's traversal state is a stack of entries ``(node, t_in, t_out, box)``. At an
inner node the two planes cut the ray interval ``[t_in, t_out]`` into the part
left of the left child's upper plane and the part right of the right child's
lower plane (children may overlap or leave a gap between them); the nearer child
(by the sign of the ray direction on the split axis) is entered, the farther one
pushed, and when neither is hit ("no child hit") the next entry is popped. The
box of each entry is the parent's box with the plane(s) applied (Algorithm 2:
LoD leaves need it for their centre); Algorithm 1 is the same walk without it.
Leaves come out front to back; callers stop early (early ray termination) simply
by not asking for the next leaf.

Everything is in the tree's own frame (index space for volumes, world space for
particles). ``grow`` widens every plane outward by a distance (the particle
renderer's radius scale), keeping the boxes conservative.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.extending import overload

from ...kernels.borrow import NO_REFCOUNT
from ...kernels.ray import slab
from ..interval import make_scratch, next_interval, record_class, start_ray
from .construct import LEAF
from .pack import Q_NEG_INF, Q_POS_INF, dequantize_plane

__all__ = ["BihRecord", "BihApproxRecord", "decode_inner", "node_kind", "traversal_arrays",
           "push_root", "next_leaf", "set_ray"]


class BihRecord(NamedTuple):
    """A packed BIH as the traversal reads it (see :class:`.build.PackedBIH`).

    Attributes
    ----------
    nodes : (slots,) int64
        Packed node words.
    preorder : bool
        Pre-order layout (else tree chunks).
    frame_lo, frame_step : (3,) float64
        Plane dequantisation frame.
    root_box : (6,) float64
    depth : int
    """

    SCRATCH = True

    nodes: np.ndarray
    preorder: bool
    frame_lo: np.ndarray
    frame_step: np.ndarray
    root_box: np.ndarray
    depth: int


class BihApproxRecord(NamedTuple):
    """BIH-DVR (approximate): the tree plus what its per-leaf integrators need.

    ``mode`` is :data:`.integrate.MODE_SINGLE` or ``MODE_MULTI``; a leaf's 14-bit
    density ``d`` stands for the value ``d_lo + d * d_span``, its gradient codes
    are scaled by ``grad_scale`` (see :mod:`.integrate`).
    """

    LATTICE = False
    SCRATCH = True

    tree: BihRecord
    mode: int
    grad_scale: float
    d_lo: float
    d_span: float


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def decode_inner(nodes, i, preorder):
    """``(axis, first, second, single, q0, q1)`` of inner node ``i``; ``second`` is -1
    for a single child. See :func:`sparsecast.index.bih.pack.pack_nodes`."""
    w = nodes[i]
    axis = (w >> 62) & 3
    field = (w >> 32) & 0x3FFFFFFF
    q0 = w & 0xFFFF
    q1 = (w >> 16) & 0xFFFF
    if preorder:
        single = field == i + 1
        first = i + 1
        second = field
    else:
        single = (field & 1) == 1
        first = field & ~1
        second = first + 1
    if single:
        second = -1
    return axis, first, second, single, q0, q1


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def node_kind(nodes, i):
    return (nodes[i] >> 62) & 3


#: ``[t0, t1]`` restricted to ``lo <= o + t d <= hi`` on one axis (``inv = 1/d``)
_cut = slab


@njit(cache=True)
def traversal_arrays(depth):
    """Per-tile scratch of a traversal of a tree of ``depth``: the stack
    ``(st_node, st_t, st_box)`` (``depth + 2`` entries: one far child per level),
    the leaf box and the per-ray ``ro``, ``rinv``, ``rflat`` (see :func:`set_ray`)."""
    cap = depth + 2
    return (np.empty(cap, np.int64), np.empty((cap, 2), np.float64), np.empty((cap, 6), np.float64),
            np.empty(6, np.float64), np.empty(3, np.float64), np.empty(3, np.float64), np.empty(3, np.bool_))


@njit(cache=True, **NO_REFCOUNT)
def push_root(box, ro, rinv, rflat, t0, t1, st_node, st_t, st_box):
    """Start a traversal: clip ``[t0, t1]`` to the root ``box``; returns the stack size (0 or 1)."""
    for a in range(3):
        t0, t1 = _cut(ro[a], rinv[a], rflat[a], box[a], box[3 + a], t0, t1)
    if t0 > t1:
        return 0
    st_node[0] = 0
    st_t[0, 0] = t0
    st_t[0, 1] = t1
    for a in range(6):
        st_box[0, a] = box[a]
    return 1


@njit(cache=True, **NO_REFCOUNT)
def next_leaf(nodes, preorder, frame_lo, frame_step, grow, ro, rinv, rflat, st_node, st_t, st_box, hs,
              leaf_box):
    """Walk to the next leaf in front-to-back order.

    Returns ``(leaf, t_in, t_out, hs)``; ``leaf`` is -1 when the traversal is over.
    The leaf's box is written to ``leaf_box``. ``ro``, ``rinv``, ``rflat``: ray origin,
    ``1/d`` and ``d == 0`` per axis; ``st_*``: the stack (``depth + 1`` entries).
    """
    while hs > 0:
        hs -= 1
        node = st_node[hs]
        t0 = st_t[hs, 0]
        t1 = st_t[hs, 1]
        for a in range(6):
            leaf_box[a] = st_box[hs, a]
        while True:
            axis, first, second, single, q0, q1 = decode_inner(nodes, node, preorder)
            if axis == LEAF:
                return node, t0, t1, hs
            flo = frame_lo[axis]
            fst = frame_step[axis]
            o = ro[axis]
            inv = rinv[axis]
            flat = rflat[axis]
            if single:
                if q1 == Q_POS_INF:  # only the left child
                    lo = -math.inf
                    hi = dequantize_plane(q0, flo, fst) + grow
                elif q0 == Q_NEG_INF:  # only the right child
                    lo = dequantize_plane(q1, flo, fst) - grow
                    hi = math.inf
                else:  # elaborate: both planes bound the one child
                    lo = dequantize_plane(q0, flo, fst) - grow
                    hi = dequantize_plane(q1, flo, fst) + grow
                t0, t1 = _cut(o, inv, flat, lo, hi, t0, t1)
                if t0 > t1:
                    break
                leaf_box[axis] = max(leaf_box[axis], lo)
                leaf_box[3 + axis] = min(leaf_box[3 + axis], hi)
                node = first
                continue
            pl = dequantize_plane(q0, flo, fst) + grow  # left child's upper plane
            pr = dequantize_plane(q1, flo, fst) - grow  # right child's lower plane
            l0, l1 = _cut(o, inv, flat, -math.inf, pl, t0, t1)
            r0, r1 = _cut(o, inv, flat, pr, math.inf, t0, t1)
            hit_l = l0 <= l1
            hit_r = r0 <= r1
            if hit_l and hit_r:
                # near child first: the left one unless the ray runs towards -axis
                if inv < 0.0 and not flat:
                    st_node[hs] = first
                    st_t[hs, 0] = l0
                    st_t[hs, 1] = l1
                    for a in range(6):
                        st_box[hs, a] = leaf_box[a]
                    st_box[hs, 3 + axis] = min(leaf_box[3 + axis], pl)
                    hs += 1
                    node = second
                    t0, t1 = r0, r1
                    leaf_box[axis] = max(leaf_box[axis], pr)
                else:
                    st_node[hs] = second
                    st_t[hs, 0] = r0
                    st_t[hs, 1] = r1
                    for a in range(6):
                        st_box[hs, a] = leaf_box[a]
                    st_box[hs, axis] = max(leaf_box[axis], pr)
                    hs += 1
                    node = first
                    t0, t1 = l0, l1
                    leaf_box[3 + axis] = min(leaf_box[3 + axis], pl)
            elif hit_l:
                node = first
                t0, t1 = l0, l1
                leaf_box[3 + axis] = min(leaf_box[3 + axis], pl)
            elif hit_r:
                node = second
                t0, t1 = r0, r1
                leaf_box[axis] = max(leaf_box[axis], pr)
            else:  # no child hit: take the next entry from the stack
                break
    return -1, 0.0, 0.0, 0


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def set_ray(ro, rinv, rflat, ox, oy, oz, dx, dy, dz):
    """Fill the per-ray arrays :func:`next_leaf` reads."""
    ro[0] = ox
    ro[1] = oy
    ro[2] = oz
    rflat[0] = dx == 0.0
    rflat[1] = dy == 0.0
    rflat[2] = dz == 0.0
    rinv[0] = 1.0 / dx if dx != 0.0 else 0.0
    rinv[1] = 1.0 / dy if dy != 0.0 else 0.0
    rinv[2] = 1.0 / dz if dz != 0.0 else 0.0


def tree_of(record):  # pragma: no cover - jitted only
    """The :class:`BihRecord` inside either BIH record type."""
    raise NotImplementedError


@overload(tree_of, jit_options={"cache": True}, inline="always")
def _tree_of(record):
    cls = record_class(record)
    if cls is BihRecord:
        return lambda record: record
    if cls is BihApproxRecord:
        return lambda record: record.tree


def _is_bih(record) -> bool:
    return record_class(record) in (BihRecord, BihApproxRecord)


@overload(make_scratch, jit_options={"cache": True}, inline="always")
def _scratch(record):
    if _is_bih(record):
        return lambda record: traversal_arrays(tree_of(record).depth)


@overload(start_ray, jit_options={"cache": True}, inline="always")
def _start(record, scratch, ray, t_lo, t_hi):
    if _is_bih(record):

        def impl(record, scratch, ray, t_lo, t_hi):
            tree = tree_of(record)
            st_node, st_t, st_box, leaf_box, ro, rinv, rflat = scratch
            ox, oy, oz, dx, dy, dz = ray
            set_ray(ro, rinv, rflat, ox, oy, oz, dx, dy, dz)
            hs = 0
            if tree.nodes.shape[0] > 0:
                hs = push_root(tree.root_box, ro, rinv, rflat, t_lo, t_hi, st_node, st_t, st_box)
            return (hs, -1)

        return impl


@overload(next_interval, jit_options={"cache": True}, inline="always")
def _next(record, scratch, ray, state, t_covered):
    if _is_bih(record):

        def impl(record, scratch, ray, state, t_covered):
            tree = tree_of(record)
            st_node, st_t, st_box, leaf_box, ro, rinv, rflat = scratch
            hs = state[0]
            leaf, t0, t1, hs = next_leaf(tree.nodes, tree.preorder, tree.frame_lo, tree.frame_step, 0.0,
                                         ro, rinv, rflat, st_node, st_t, st_box, hs, leaf_box)
            if leaf < 0:
                return math.inf, -math.inf, (0, -1)
            return t0, t1, (hs, leaf)

        return impl
