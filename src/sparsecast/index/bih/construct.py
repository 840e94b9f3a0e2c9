"""Numba construction kernels of the bounding interval hierarchy (see :mod:`.build`).

Iterative construction with an explicit task stack and an in-place partition, as
array-in / array-out ``@njit`` functions. The level-of-detail cut is in
:mod:`.lod`, the fixed-point packing in :mod:`.pack`, traversal in :mod:`.traversal`.

Node fields of the (unpacked) tree, one row per node in depth-first pre-order:

``kind``   0, 1, 2: inner node splitting that axis; 3: leaf (:data:`LEAF`)
``child``  ``(c0, c1)``; two children: ``c0`` is bounded above by ``plane[0]``
           (the left child), ``c1`` below by ``plane[1]`` (the right child);
           one child: ``c0``, ``c1 = -1``, the child's interval on the axis is
           ``[plane[0], plane[1]]`` (``-inf`` / ``+inf`` on a side left open)
``first``, ``count``  the node's elements: ``perm[first:first + count]``
``box``    the node's box as the traversal derives it from the planes
``depth``  root = 0
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: ``kind`` of a leaf (inner nodes store their split axis 0, 1, 2)
LEAF = 3
#: construction variants: an empty child's plane is +-inf (basic), or the single
#: child takes both planes (elaborate)
BASIC, ELABORATE = 0, 1
#: one-sided halvings of the split box after which a node falls back to splitting
#: at the smallest centre (guarantees progress when centres differ by an ulp)
MAX_HALVINGS = 64

# Task record layout (float part): split box S, traversal box T, element AABB A,
# centre bounds C, 6 values each (lo x, y, z, hi x, y, z).
_S, _T, _A, _C = 0, 6, 12, 18
_TASK_F = 24
# int part: first, end, parent, slot, depth
_TASK_I = 5


@njit(cache=True)
def _grow2(a, n):
    """``a`` (C-contiguous) in a new array of ``n`` rows, the rows past ``a``'s unset."""
    out = np.empty((n,) + a.shape[1:], a.dtype)
    # Element loops rather than slice assignments here and below: a slice assignment
    # compiles Numba's shape-mismatch message with it (string formatting, 4 s of a cold
    # build for a message a correct copy never shows).
    _copy(a.ravel(), out.ravel())
    return out


@njit(cache=True)
def _copy(src, dst):
    """``dst[:len(src)] = src`` for 1-D arrays, without the shape check (see :func:`_grow2`)."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@njit(cache=True)
def _bounds(lo, hi, b, e, out, off):
    """AABB of elements ``b..e-1`` into ``out[off:off+6]`` and centre bounds into
    ``out[off+6:off+12]`` (accumulated in registers: one sequential pass)."""
    l0 = l1 = l2 = c0 = c1 = c2 = math.inf
    h0 = h1 = h2 = d0 = d1 = d2 = -math.inf
    for i in range(b, e):
        x0 = lo[i, 0]
        x1 = lo[i, 1]
        x2 = lo[i, 2]
        y0 = hi[i, 0]
        y1 = hi[i, 1]
        y2 = hi[i, 2]
        l0 = min(l0, x0)
        l1 = min(l1, x1)
        l2 = min(l2, x2)
        h0 = max(h0, y0)
        h1 = max(h1, y1)
        h2 = max(h2, y2)
        m0 = 0.5 * (x0 + y0)
        m1 = 0.5 * (x1 + y1)
        m2 = 0.5 * (x2 + y2)
        c0 = min(c0, m0)
        c1 = min(c1, m1)
        c2 = min(c2, m2)
        d0 = max(d0, m0)
        d1 = max(d1, m1)
        d2 = max(d2, m2)
    out[off + 0] = l0
    out[off + 1] = l1
    out[off + 2] = l2
    out[off + 3] = h0
    out[off + 4] = h1
    out[off + 5] = h2
    out[off + 6] = c0
    out[off + 7] = c1
    out[off + 8] = c2
    out[off + 9] = d0
    out[off + 10] = d1
    out[off + 11] = d2


@njit(cache=True)
def _swap(lo, hi, perm, i, j):
    for a in range(3):
        t = lo[i, a]
        lo[i, a] = lo[j, a]
        lo[j, a] = t
        t = hi[i, a]
        hi[i, a] = hi[j, a]
        hi[j, a] = t
    p = perm[i]
    perm[i] = perm[j]
    perm[j] = p


@njit(cache=True)
def _partition(lo, hi, perm, b, e, axis, mid, use_le, lb, rb):
    """Quicksort-like in-place partition of elements ``b..e-1`` by AABB centre.

    Left: centre < ``mid`` (``<=`` when ``use_le``). Then the AABB and centre bounds
    of each side go to ``lb`` / ``rb`` (12 values: AABB lo, hi, centre lo, hi);
    ``lb[3 + axis]`` is the left plane (max of the left elements), ``rb[axis]`` the
    right plane (min of the right ones). Returns the first index of the right side.
    """
    i = b
    j = e - 1
    while True:
        while i <= j:
            c = 0.5 * (lo[i, axis] + hi[i, axis])
            if not (c < mid or (use_le and c == mid)):
                break
            i += 1
        while i <= j:
            c = 0.5 * (lo[j, axis] + hi[j, axis])
            if c < mid or (use_le and c == mid):
                break
            j -= 1
        if i >= j:
            break
        _swap(lo, hi, perm, i, j)
        i += 1
        j -= 1
    _bounds(lo, hi, b, i, lb, 0)
    _bounds(lo, hi, i, e, rb, 0)
    return i


@njit(cache=True)
def _emit(node_i, node_f, node_box, node, parent, slot, kind, b, e, depth, p0, p1, cur):
    """Write node ``node`` (children unset: -1) and link it as child ``slot`` of ``parent``."""
    if parent >= 0:
        node_i[parent, 1 + slot] = node
    node_i[node, 0] = kind
    node_i[node, 1] = -1
    node_i[node, 2] = -1
    node_i[node, 3] = b
    node_i[node, 4] = e - b
    node_i[node, 5] = depth
    node_f[node, 0] = p0
    node_f[node, 1] = p1
    for a in range(6):
        node_box[node, a] = cur[_T + a]


@njit(cache=True)
def _emit_single(node_i, node_f, node_box, node, parent, slot, axis, b, e, depth, lo_p, hi_p, cur):
    """Write a single-child node with interval ``[lo_p, hi_p]`` on ``axis`` and cut
    the task's traversal box T down to it (the child continues the task)."""
    _emit(node_i, node_f, node_box, node, parent, slot, axis, b, e, depth, lo_p, hi_p, cur)
    cur[_T + axis] = max(cur[_T + axis], lo_p)
    cur[_T + 3 + axis] = min(cur[_T + 3 + axis], hi_p)


@njit(cache=True)
def build(lo, hi, variant, node_i, node_f, node_box, perm):
    """Build the intermediate BIH over element AABBs ``lo``/``hi`` (n, 3), in place.

    ``lo``, ``hi`` and ``perm`` (``arange(n)``) are permuted so that every node's
    elements are contiguous. ``node_i`` (cap, 6) int64 receives ``kind, c0, c1,
    first, count, depth``; ``node_f`` (cap, 2) float64 the planes; ``node_box``
    (cap, 6) float64 the boxes. Arrays are grown as needed and returned with the
    node count: ``(m, node_i, node_f, node_box)``.

    Each task is a node to make: its elements, its split box ``S`` (regular
    halving of the root AABB, used only to choose split planes), its traversal
    box ``T`` (what the planes above it cut out) and its elements' AABB and centre
    bounds (from the parent's partition pass). A task loops: split ``S`` at the
    middle of its longest axis; both sides non-empty -> an inner node with planes
    (max of the left, min of the right) and two child tasks; one side empty -> ``S``
    shrinks to that half, and where the elements' planes cut ``T`` a single-child
    node records them (basic: the non-empty side's plane, elaborate: both); until
    all centres coincide and ``T`` equals the elements' AABB, which makes a leaf
    (one element, or several identical ones).
    """
    n = lo.shape[0]
    m = 0
    cap_t = 256
    tf = np.empty((cap_t, _TASK_F), np.float64)
    ti = np.empty((cap_t, _TASK_I), np.int64)
    cur = np.empty(_TASK_F, np.float64)
    lb = np.empty(12, np.float64)
    rb = np.empty(12, np.float64)
    if n == 0:
        return 0, node_i, node_f, node_box
    _bounds(lo, hi, 0, n, cur, _A)
    for a in range(6):
        cur[_S + a] = cur[_A + a]
        cur[_T + a] = cur[_A + a]
    _copy(cur, tf[0])
    ti[0, 0] = 0
    ti[0, 1] = n
    ti[0, 2] = -1
    ti[0, 3] = 0
    ti[0, 4] = 0
    hs = 1
    while hs > 0:
        hs -= 1
        _copy(tf[hs], cur)
        b = ti[hs, 0]
        e = ti[hs, 1]
        parent = ti[hs, 2]
        slot = ti[hs, 3]
        depth = ti[hs, 4]
        halvings = 0
        while True:
            if m + 1 >= node_i.shape[0]:
                cap = 2 * node_i.shape[0] + 16
                node_i = _grow2(node_i, cap)
                node_f = _grow2(node_f, cap)
                node_box = _grow2(node_box, cap)
            # Which axis still separates the centres, and which one T overhangs.
            same = True
            for a in range(3):
                if cur[_C + a] < cur[_C + 3 + a]:
                    same = False
            if same:
                # All centres coincide: a leaf once T is the elements' AABB,
                # otherwise a single-child node cutting T down on one axis.
                best = -1
                gap = 0.0
                for a in range(3):
                    g = (cur[_A + a] - cur[_T + a]) + (cur[_T + 3 + a] - cur[_A + 3 + a])
                    if g > gap:
                        gap = g
                        best = a
                if best < 0:
                    _emit(node_i, node_f, node_box, m, parent, slot, LEAF, b, e, depth, 0.0, 0.0, cur)
                    m += 1
                    break
                a = best
                lo_p = cur[_A + a]
                hi_p = cur[_A + 3 + a]
                if variant == BASIC:
                    # one plane per node: cut the lower side first
                    if cur[_T + a] < lo_p:
                        hi_p = math.inf
                    else:
                        lo_p = -math.inf
                _emit_single(node_i, node_f, node_box, m, parent, slot, a, b, e, depth, lo_p, hi_p, cur)
                parent = m
                m += 1
                slot = 0
                depth += 1
                continue
            # Split plane: the middle of S's longest axis (or, after too many
            # one-sided halvings, the smallest centre on the widest centre axis).
            use_le = halvings >= MAX_HALVINGS
            if use_le:
                axis = 0
                w = -1.0
                for a in range(3):
                    if cur[_C + 3 + a] - cur[_C + a] > w:
                        w = cur[_C + 3 + a] - cur[_C + a]
                        axis = a
                mid = cur[_C + axis]
            else:
                axis = 0
                w = -1.0
                for a in range(3):
                    if cur[_S + 3 + a] - cur[_S + a] > w:
                        w = cur[_S + 3 + a] - cur[_S + a]
                        axis = a
                mid = 0.5 * (cur[_S + axis] + cur[_S + 3 + axis])
            k = _partition(lo, hi, perm, b, e, axis, mid, use_le, lb, rb)
            if k == b or k == e:
                # One side empty: no split here; S shrinks to the occupied half.
                halvings += 1
                if k == b:
                    cur[_S + axis] = mid
                else:
                    cur[_S + 3 + axis] = mid
                lo_p = cur[_A + axis]
                hi_p = cur[_A + 3 + axis]
                cut_lo = lo_p > cur[_T + axis]
                cut_hi = hi_p < cur[_T + 3 + axis]
                if variant == BASIC:
                    # only the non-empty child's plane; the empty one is +-inf
                    if k == b:
                        hi_p = math.inf
                        cut_hi = False
                    else:
                        lo_p = -math.inf
                        cut_lo = False
                if cut_lo or cut_hi:
                    _emit_single(node_i, node_f, node_box, m, parent, slot, axis, b, e, depth, lo_p, hi_p, cur)
                    parent = m
                    m += 1
                    slot = 0
                    depth += 1
                continue
            # Two children.
            node = m
            m += 1
            _emit(node_i, node_f, node_box, node, parent, slot, axis, b, e, depth, lb[3 + axis], rb[axis], cur)
            if hs + 2 > cap_t:
                cap_t *= 2
                tf = _grow2(tf, cap_t)
                ti = _grow2(ti, cap_t)
            # Right task first: the left child is popped next (pre-order).
            for side in range(2):
                t = hs + side
                _copy(cur, tf[t])
                src = rb if side == 0 else lb
                for a in range(6):
                    tf[t, _A + a] = src[a]
                    tf[t, _C + a] = src[6 + a]
                if side == 0:
                    tf[t, _S + axis] = mid
                    tf[t, _T + axis] = max(cur[_T + axis], rb[axis])
                    ti[t, 0] = k
                    ti[t, 1] = e
                    ti[t, 3] = 1
                else:
                    tf[t, _S + 3 + axis] = mid
                    tf[t, _T + 3 + axis] = min(cur[_T + 3 + axis], lb[3 + axis])
                    ti[t, 0] = b
                    ti[t, 1] = k
                    ti[t, 3] = 0
                ti[t, 2] = node
                ti[t, 4] = depth + 1
            hs += 2
            break
    return m, node_i, node_f, node_box
