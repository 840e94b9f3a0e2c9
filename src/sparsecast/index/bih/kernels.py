"""Numba build kernels of the bounding interval hierarchy (see :mod:`sparsecast.index.bih`).

Construction (iterative, explicit task stack, in-place partition), bottom-up
statistics, the static LoD cut, fixed-point packing and the tree-chunk layout, as
array-in / array-out ``@njit`` functions. Traversal lives in
:mod:`sparsecast.index.bih.traversal`.

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
    out = np.empty((n,) + a.shape[1:], a.dtype)
    out[: a.shape[0]] = a
    return out


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
    tf[0] = cur
    ti[0, 0] = 0
    ti[0, 1] = n
    ti[0, 2] = -1
    ti[0, 3] = 0
    ti[0, 4] = 0
    hs = 1
    while hs > 0:
        hs -= 1
        cur[:] = tf[hs]
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
                tf[t] = cur
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


@njit(cache=True)
def node_stats(kind, child, first, count, elem_volume, density, gradient, out_vol, out_mean, out_m2, out_grad):
    """Per-node statistics combined bottom-up (children follow parents in pre-order).

    Leaves reduce their elements; an inner node combines its children: element
    volume sums, mean density and its sum of squared deviations (Chan et al.'s
    pairwise update, weighted by element counts) and mean gradient. Element arrays
    are in the tree's element order.
    """
    m = kind.shape[0]
    for i in range(m - 1, -1, -1):
        if kind[i] == LEAF:
            b = first[i]
            e = b + count[i]
            v = 0.0
            s = 0.0
            g0 = 0.0
            g1 = 0.0
            g2 = 0.0
            for j in range(b, e):
                v += elem_volume[j]
                s += density[j]
                g0 += gradient[j, 0]
                g1 += gradient[j, 1]
                g2 += gradient[j, 2]
            nn = e - b
            mean = s / nn
            m2 = 0.0
            for j in range(b, e):
                dd = density[j] - mean
                m2 += dd * dd
            out_vol[i] = v
            out_mean[i] = mean
            out_m2[i] = m2
            out_grad[i, 0] = g0 / nn
            out_grad[i, 1] = g1 / nn
            out_grad[i, 2] = g2 / nn
            continue
        c0 = child[i, 0]
        c1 = child[i, 1]
        if c1 < 0:
            out_vol[i] = out_vol[c0]
            out_mean[i] = out_mean[c0]
            out_m2[i] = out_m2[c0]
            for a in range(3):
                out_grad[i, a] = out_grad[c0, a]
            continue
        na = float(count[c0])
        nb = float(count[c1])
        nab = na + nb
        delta = out_mean[c1] - out_mean[c0]
        out_vol[i] = out_vol[c0] + out_vol[c1]
        out_mean[i] = out_mean[c0] + delta * nb / nab
        out_m2[i] = out_m2[c0] + out_m2[c1] + delta * delta * na * nb / nab
        for a in range(3):
            out_grad[i, a] = (na * out_grad[c0, a] + nb * out_grad[c1, a]) / nab


@njit(cache=True)
def lod_cut(kind, child, box, count, vol, mean, m2, max_depth, min_fill, max_std, keep):
    """Mark the nodes of the static LoD cut; returns ``(nodes, depth)`` of the cut.

    Top-down: a node is kept; it becomes a LoD leaf when it is a leaf already, at
    ``max_depth``, or when its elements fill at least ``min_fill`` of its box and
    the standard deviation of their density is at most ``max_std``. ``keep`` (m,)
    int64 receives -1 for nodes below the cut, 0 for kept inner nodes and 1 for LoD
    leaves.
    """
    m = kind.shape[0]
    stack = np.empty(m + 1, np.int64)
    dstack = np.empty(m + 1, np.int64)
    keep[:] = -1
    if m == 0:
        return 0, 0
    stack[0] = 0
    dstack[0] = 0
    hs = 1
    nodes = 0
    deepest = 0
    while hs > 0:
        hs -= 1
        i = stack[hs]
        d = dstack[hs]
        nodes += 1
        deepest = max(deepest, d)
        leaf = kind[i] == LEAF or d >= max_depth
        if not leaf:
            bv = 1.0
            for a in range(3):
                bv *= box[i, 3 + a] - box[i, a]
            fill = vol[i] / bv if bv > 0.0 else 1.0
            std = math.sqrt(max(m2[i], 0.0) / count[i])
            leaf = fill >= min_fill and std <= max_std
        if leaf:
            keep[i] = 1
            continue
        keep[i] = 0
        c1 = child[i, 1]
        if c1 >= 0:
            stack[hs] = c1
            dstack[hs] = d + 1
            hs += 1
        stack[hs] = child[i, 0]
        dstack[hs] = d + 1
        hs += 1
    return nodes, deepest


@njit(cache=True)
def compact_cut(keep, child, new_child, new_depth):
    """Renumber the kept nodes (pre-order is preserved): returns the old ids in new
    order; ``new_child`` (k, 2) receives the renumbered children (-1 under LoD
    leaves) and ``new_depth`` (k,) the depths."""
    m = keep.shape[0]
    new_id = np.full(m, -1, np.int64)
    k = 0
    for i in range(m):
        if keep[i] >= 0:
            new_id[i] = k
            k += 1
    old = np.empty(k, np.int64)
    for i in range(m):
        j = new_id[i]
        if j >= 0:
            old[j] = i
            if keep[i] == 1:
                new_child[j, 0] = -1
                new_child[j, 1] = -1
            else:
                c0 = child[i, 0]
                c1 = child[i, 1]
                new_child[j, 0] = new_id[c0]
                new_child[j, 1] = new_id[c1] if c1 >= 0 else -1
    for j in range(k):  # pre-order: a parent precedes its children
        if j == 0:
            new_depth[0] = 0
        for s in range(2):
            c = new_child[j, s]
            if c >= 0:
                new_depth[c] = new_depth[j] + 1
    return old


# -- packing -------------------------------------------------------------------------
#: fixed-point plane codes: 0x4000 is 0 and 0xC000 is 1 in normalised space
Q_ZERO, Q_ONE = 0x4000, 0xC000
Q_NEG_INF, Q_POS_INF = 0x0000, 0xFFFF
DENSITY_MAX = (1 << 14) - 1
GRAD_ZERO = 0x8000
GRAD_MAX = 0x7FFF


@njit(cache=True, inline="always")
def quantize_plane(x, lo, ext, up):
    """16-bit code of plane ``x`` in the frame ``[lo, lo + ext]``, rounded outward
    (``up``: towards +inf, for upper bounds), so that boxes only grow; +-inf map to
    0xFFFF / 0x0000 and finite planes to ``1..0xFFFE``."""
    if x == math.inf:
        return Q_POS_INF
    if x == -math.inf:
        return Q_NEG_INF
    u = (x - lo) / ext * (Q_ONE - Q_ZERO) + Q_ZERO
    q = math.ceil(u) if up else math.floor(u)
    return int(min(max(q, 1.0), float(Q_POS_INF - 1)))


@njit(cache=True, inline="always")
def dequantize_plane(q, lo, step):
    """Plane position of code ``q`` (``step = ext / 0x8000``)."""
    if q == Q_POS_INF:
        return math.inf
    if q == Q_NEG_INF:
        return -math.inf
    return lo + (q - Q_ZERO) * step


@njit(cache=True)
def pack_nodes(kind, child, plane, density, gradient, leaf_first, leaf_count, frame_lo, frame_ext,
               grad_scale, particles, slot_of, field_of, out):
    """Encode every node into one 64-bit word (stored as int64; see :mod:`.bih`).

    ``slot_of[i]`` is node ``i``'s position in ``out``; ``field_of[i]`` its 30-bit
    child field (computed by the layout). Inner: bits 62-63 axis, 32-61 child
    field, 16-31 plane 1, 0-15 plane 0. Leaf: bits 62-63 = 3 and either the density
    (14 bits, 48-61) and gradient (x: 0-15, y: 16-31, z: 32-47), or, for particle
    trees, the first element (32-61) and count (0-31).
    """
    for i in range(kind.shape[0]):
        k = kind[i]
        if k == LEAF:
            w = np.int64(LEAF) << 62
            if particles:
                w |= np.int64(leaf_first[i]) << 32
                w |= np.int64(leaf_count[i])
            else:
                dq = int(round(min(max(density[i], 0.0), 1.0) * DENSITY_MAX))
                w |= np.int64(dq) << 48
                for a in range(3):
                    g = gradient[i, a] / grad_scale if grad_scale > 0.0 else 0.0
                    gq = int(round(min(max(g, -1.0), 1.0) * GRAD_MAX)) + GRAD_ZERO
                    w |= np.int64(gq) << (16 * a)
        else:
            a = k
            if child[i, 1] >= 0:  # two children: left upper bound, right lower bound
                q0 = quantize_plane(plane[i, 0], frame_lo[a], frame_ext[a], True)
                q1 = quantize_plane(plane[i, 1], frame_lo[a], frame_ext[a], False)
            elif plane[i, 0] == -math.inf:  # basic, only the left child: its upper bound
                q0 = quantize_plane(plane[i, 1], frame_lo[a], frame_ext[a], True)
                q1 = Q_POS_INF  # the empty right child's invalid plane
            elif plane[i, 1] == math.inf:  # basic, only the right child: its lower bound
                q0 = Q_NEG_INF  # the empty left child's invalid plane
                q1 = quantize_plane(plane[i, 0], frame_lo[a], frame_ext[a], False)
            else:  # elaborate single child: [lower, upper]
                q0 = quantize_plane(plane[i, 0], frame_lo[a], frame_ext[a], False)
                q1 = quantize_plane(plane[i, 1], frame_lo[a], frame_ext[a], True)
            w = (np.int64(a) << 62) | (np.int64(field_of[i]) << 32) | (np.int64(q1) << 16) | np.int64(q0)
        out[slot_of[i]] = w


@njit(cache=True)
def preorder_fields(child, field_of):
    """Child fields of the pre-order layout: the right child's index for two
    children (the left one follows its parent), ``i + 1`` for a single child."""
    for i in range(child.shape[0]):
        if child[i, 0] < 0:
            field_of[i] = 0
        elif child[i, 1] >= 0:
            field_of[i] = child[i, 1]
        else:
            field_of[i] = i + 1


@njit(cache=True)
def chunk_layout(child, chunk_depth, slot_of, field_of):
    """Tree-chunk layout: siblings stored as an aligned pair, chunks of
    ``chunk_depth`` levels of sibling pairs stored together, chunks depth first.

    Slot 0 holds the root (slot 1 is padding); every group of children starts at
    an even slot; a single child occupies the first slot of its pair, and its
    parent's field has bit 0 set. Returns the number of slots.
    """
    m = child.shape[0]
    # chunk roots: pending groups (a parent whose children start a new chunk)
    pending = np.empty(m + 1, np.int64)
    level = np.empty(m + 1, np.int64)
    nxt = np.empty(m + 1, np.int64)
    slot_of[0] = 0
    next_slot = 2
    np_ = 0
    if child[0, 0] >= 0:
        pending[0] = 0
        np_ = 1
    while np_ > 0:
        np_ -= 1
        # breadth first over chunk_depth levels of groups below this parent
        level[0] = pending[np_]
        nl = 1
        for _ in range(chunk_depth):
            nn = 0
            for p in range(nl):
                parent = level[p]
                c0 = child[parent, 0]
                c1 = child[parent, 1]
                s = next_slot
                next_slot += 2
                slot_of[c0] = s
                if c1 >= 0:
                    slot_of[c1] = s + 1
                    field_of[parent] = s
                else:
                    field_of[parent] = s | 1
                for c in (c0, c1):
                    if c >= 0 and child[c, 0] >= 0:
                        nxt[nn] = c
                        nn += 1
            for p in range(nn):
                level[p] = nxt[p]
            nl = nn
            if nl == 0:
                break
        # groups below the chunk start chunks of their own (reverse: depth first)
        for p in range(nl - 1, -1, -1):
            pending[np_] = level[p]
            np_ += 1
    for i in range(m):
        if child[i, 0] < 0:
            field_of[i] = 0
    return next_slot
