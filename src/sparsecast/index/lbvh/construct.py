"""Numba build kernels of the LBVH over bricks (see :mod:`sparsecast.index.lbvh`).

Compaction, Morton codes, radix sort, Karras' hierarchy, refit and pruning, as
small array-in / array-out ``@njit`` functions (no Python objects), so a CUDA
backend could mirror them.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numba.cpython.unsafe.numbers import leading_zeros

from ...kernels.classify import classify_ranges

#: bricks per axis that 30-bit Morton codes (10 bits per axis) can address
MORTON30_MAX = 1 << 10
#: bricks per axis that 63-bit Morton codes (21 bits per axis) can address
MORTON63_MAX = 1 << 21
#: below this many items the "parallel" build kernels run their loop serially:
#: waking the thread pool costs more than the work (and is erratic under load)
PARALLEL_MIN = 1 << 16


# -- voting -------------------------------------------------------------------------
def classify_bricks(prefix, v_lo, scale, vmin, vmax):
    """Flat occupancy of bricks with value ranges ``vmin``/``vmax`` (flat float64).

    The TF range query of :meth:`TransferFunction.classify` (the same kernel, which
    runs serially below :data:`sparsecast.kernels.classify.PARALLEL_MIN` ranges).
    """
    out = np.empty(vmin.shape[0], np.bool_)
    classify_ranges(prefix, v_lo, scale, vmin, vmax, out)
    return out


# -- compaction ---------------------------------------------------------------
@njit(cache=True)
def compact(occupied):
    """Flat ids of the non-empty bricks, ascending, by an exclusive prefix sum.

    ``occupied`` is the flat (C-order) brick occupancy. Serial: at the brick counts
    of interest (10^4..10^6) the scan is memory bound and takes microseconds.
    """
    n = occupied.shape[0]
    offs = np.empty(n + 1, np.int64)
    s = 0
    for i in range(n):
        offs[i] = s
        if occupied[i]:
            s += 1
    offs[n] = s
    ids = np.empty(s, np.int64)
    for i in range(n):
        if occupied[i]:
            ids[offs[i]] = i
    return ids


# -- Morton codes -------------------------------------------------------------
@njit(cache=True, inline="always")
def _spread10(x):
    """Insert two zero bits between each of the low 10 bits of ``x``."""
    x &= 0x3FF
    x = (x | (x << 16)) & 0x030000FF
    x = (x | (x << 8)) & 0x0300F00F
    x = (x | (x << 4)) & 0x030C30C3
    x = (x | (x << 2)) & 0x09249249
    return x


@njit(cache=True, inline="always")
def _spread21(x):
    """Insert two zero bits between each of the low 21 bits of ``x``."""
    x &= 0x1FFFFF
    x = (x | (x << 32)) & 0x1F00000000FFFF
    x = (x | (x << 16)) & 0x1F0000FF0000FF
    x = (x | (x << 8)) & 0x100F00F00F00F00F
    x = (x | (x << 4)) & 0x10C30C30C30C30C3
    x = (x | (x << 2)) & 0x1249249249249249
    return x


@njit(cache=True)
def morton30(x, y, z):
    """30-bit Morton code of ``(x, y, z)`` (each < 1024); x in the lowest bit."""
    return _spread10(np.int64(x)) | (_spread10(np.int64(y)) << 1) | (_spread10(np.int64(z)) << 2)


@njit(cache=True)
def morton63(x, y, z):
    """63-bit Morton code of ``(x, y, z)`` (each < 2^21); x in the lowest bit."""
    return _spread21(np.int64(x)) | (_spread21(np.int64(y)) << 1) | (_spread21(np.int64(z)) << 2)


@njit(cache=True)
def _morton_one(ids, i, plane, nbx, wide, out):
    f = ids[i]
    bz = f // plane
    r = f - bz * plane
    by = r // nbx
    bx = r - by * nbx
    if wide:
        out[i] = morton63(bx, by, bz)
    else:
        out[i] = morton30(bx, by, bz)


@njit(cache=True, parallel=True)
def _morton_par(ids, plane, nbx, wide, out):
    for i in prange(ids.shape[0]):
        _morton_one(ids, i, plane, nbx, wide, out)


@njit(cache=True)
def morton_codes(ids, nby, nbx, wide):
    """Morton codes (int64) of the bricks with flat ids ``ids`` in a ``(nbz, nby, nbx)`` grid.

    Parallel over bricks (serial below :data:`PARALLEL_MIN` bricks).
    """
    n = ids.shape[0]
    out = np.empty(n, np.int64)
    plane = nby * nbx
    if n >= PARALLEL_MIN:
        _morton_par(ids, plane, nbx, wide, out)
    else:
        for i in range(n):
            _morton_one(ids, i, plane, nbx, wide, out)
    return out


# -- sort -----------------------------------------------------------------------
@njit(cache=True)
def radix_argsort(codes):
    """Stable LSD radix argsort of non-negative int64 keys (8-bit digits).

    Only as many passes as the largest key has bytes (4 for 30-bit codes).
    """
    n = codes.shape[0]
    perm = np.arange(n).astype(np.int64)
    if n < 2:
        return perm
    top = codes.max()
    tmp = np.empty(n, np.int64)
    count = np.empty(257, np.int64)
    shift = 0
    while shift < 64 and (top >> shift) > 0:
        count[:] = 0
        for i in range(n):
            count[((codes[perm[i]] >> shift) & 0xFF) + 1] += 1
        for d in range(256):
            count[d + 1] += count[d]
        for i in range(n):
            p = perm[i]
            d = (codes[p] >> shift) & 0xFF
            tmp[count[d]] = p
            count[d] += 1
        perm, tmp = tmp, perm
        shift += 8
    return perm


# -- hierarchy (Karras 2012) ------------------------------------------------------
@njit(cache=True, inline="always")
def _delta(codes, n, i, j):
    """Common-prefix length of keys ``i`` and ``j`` (-1 outside ``[0, n)``).

    Keys are ``(code, index)``: equal codes fall back to the index bits, so
    duplicate codes still give a well-formed tree.
    """
    if j < 0 or j >= n:
        return -1
    a = codes[i]
    b = codes[j]
    if a == b:
        return 64 + leading_zeros(np.int64(i ^ j))
    return leading_zeros(a ^ b)


@njit(cache=True)
def _karras_node(codes, n, i, left, right, parent, first, last):
    """Range, split and children of inner node ``i`` (Karras 2012, Fig. 4)."""
    d = 1 if _delta(codes, n, i, i + 1) - _delta(codes, n, i, i - 1) > 0 else -1
    dmin = _delta(codes, n, i, i - d)
    lmax = 2
    while _delta(codes, n, i, i + lmax * d) > dmin:
        lmax *= 2
    ln = 0
    t = lmax // 2
    while t >= 1:
        if _delta(codes, n, i, i + (ln + t) * d) > dmin:
            ln += t
        t //= 2
    j = i + ln * d
    dnode = _delta(codes, n, i, j)
    s = 0
    t = ln
    while True:
        t = (t + 1) // 2
        if _delta(codes, n, i, i + (s + t) * d) > dnode:
            s += t
        if t <= 1:
            break
    gamma = i + s * d + min(d, 0)
    lo = min(i, j)
    hi = max(i, j)
    lc = gamma + n - 1 if lo == gamma else gamma
    rc = gamma + n if hi == gamma + 1 else gamma + 1
    left[i] = lc
    right[i] = rc
    parent[lc] = i
    parent[rc] = i
    first[i] = lo
    last[i] = hi


@njit(cache=True, parallel=True)
def _karras_par(codes, left, right, parent, first, last):
    n = codes.shape[0]
    for i in prange(n - 1):
        _karras_node(codes, n, i, left, right, parent, first, last)


@njit(cache=True)
def karras_hierarchy(codes, left, right, parent, first, last):
    """Inner nodes of the radix tree over ``n`` sorted keys, one task per inner node.

    Node numbering: inner nodes ``0..n-2`` (root 0), leaf ``k`` is node ``n-1+k``.
    Writes ``left``/``right`` (children of inner nodes; -1 for leaves), ``parent``
    (every node; -1 for the root) and ``first``/``last`` (range of sorted leaves
    under each node) — all of length ``2n-1``. Every inner node is independent
    (parallel; serial below :data:`PARALLEL_MIN` keys).
    """
    n = codes.shape[0]
    if n >= PARALLEL_MIN:
        _karras_par(codes, left, right, parent, first, last)
    else:
        for i in range(n - 1):
            _karras_node(codes, n, i, left, right, parent, first, last)
    for k in range(n):
        node = n - 1 + k
        left[node] = -1
        right[node] = -1
        first[node] = k
        last[node] = k
    parent[0] = -1  # the root (inner node 0, or the only leaf when n == 1)


# -- refit ------------------------------------------------------------------------
@njit(cache=True)
def refit(left, right, leaf_coords, bbox, depth_out):
    """Bottom-up brick-coordinate AABBs of every node; returns the tree depth.

    ``leaf_coords`` (n, 3) int32: brick coordinates (x, y, z) of the sorted leaves.
    ``bbox`` (2n-1, 6) int32 is written with ``lo x, y, z, hi x, y, z`` (inclusive
    brick coordinates); ``depth_out`` (2n-1,) int32 with each node's depth (root 0).
    A serial post-order walk from the root with an explicit stack: O(n) and
    cache-friendly; at 10^3..10^5 leaves it takes well under a millisecond.
    """
    n = leaf_coords.shape[0]
    m = 2 * n - 1
    for k in range(n):
        node = n - 1 + k
        for a in range(3):
            bbox[node, a] = leaf_coords[k, a]
            bbox[node, 3 + a] = leaf_coords[k, a]
    stack = np.empty(m + 1, np.int64)
    sp = 0
    stack[sp] = 0
    sp += 1
    depth_out[0] = 0
    max_depth = 0
    # Pre-order pushes, then inner nodes are finished in reverse pre-order
    # (children before parents).
    order = np.empty(m, np.int64)
    no = 0
    while sp > 0:
        sp -= 1
        node = stack[sp]
        order[no] = node
        no += 1
        if depth_out[node] > max_depth:
            max_depth = depth_out[node]
        if left[node] >= 0:
            depth_out[left[node]] = depth_out[node] + 1
            depth_out[right[node]] = depth_out[node] + 1
            stack[sp] = right[node]
            stack[sp + 1] = left[node]
            sp += 2
    for q in range(no - 1, -1, -1):
        node = order[q]
        if left[node] >= 0:
            a_ = left[node]
            b_ = right[node]
            for a in range(3):
                bbox[node, a] = min(bbox[a_, a], bbox[b_, a])
                bbox[node, 3 + a] = max(bbox[a_, 3 + a], bbox[b_, 3 + a])
    return max_depth


@njit(cache=True)
def layout(left, right, bbox, first, last, prune, brick, dims, out_child, out_box, out_first, out_count):
    """Final node arrays in depth-first pre-order, optionally collapsing subtrees.

    A node becomes a leaf when it is one, or when ``prune > 0`` and its fill ratio
    (non-empty bricks under it / bricks its brick-coordinate box spans) is at least
    ``prune``. Boxes are converted from brick coordinates to index space: brick
    ``b`` spans ``[b*B, min((b+1)*B, n-1)]``. Returns the number of nodes written.
    """
    nx, ny, nz = dims[0], dims[1], dims[2]
    m = left.shape[0]
    stack = np.empty(m + 1, np.int64)   # source node
    slot = np.empty(m + 1, np.int64)    # where its id goes: parent's child slot
    dep = np.empty(m + 1, np.int64)
    stack[0] = 0
    slot[0] = -1
    dep[0] = 0
    sp = 1
    count = 0
    max_depth = 0
    while sp > 0:
        sp -= 1
        src = stack[sp]
        s = slot[sp]
        d = dep[sp]
        if d > max_depth:
            max_depth = d
        me = count
        count += 1
        if s >= 0:
            out_child[s // 2, s % 2] = me
        lo_x = bbox[src, 0] * brick
        lo_y = bbox[src, 1] * brick
        lo_z = bbox[src, 2] * brick
        hi_x = min((bbox[src, 3] + 1) * brick, nx - 1)
        hi_y = min((bbox[src, 4] + 1) * brick, ny - 1)
        hi_z = min((bbox[src, 5] + 1) * brick, nz - 1)
        out_box[me, 0] = lo_x
        out_box[me, 1] = lo_y
        out_box[me, 2] = lo_z
        out_box[me, 3] = hi_x
        out_box[me, 4] = hi_y
        out_box[me, 5] = hi_z
        nleaves = last[src] - first[src] + 1
        leaf = left[src] < 0
        if not leaf and prune > 0.0:
            span = ((bbox[src, 3] - bbox[src, 0] + 1) * (bbox[src, 4] - bbox[src, 1] + 1)
                    * (bbox[src, 5] - bbox[src, 2] + 1))
            leaf = nleaves >= prune * span
        out_first[me] = first[src]
        out_count[me] = nleaves
        if leaf:
            out_child[me, 0] = -1
            out_child[me, 1] = -1
        else:
            # Left is popped first, so it gets the next id (pre-order).
            stack[sp] = right[src]
            slot[sp] = 2 * me + 1
            dep[sp] = d + 1
            stack[sp + 1] = left[src]
            slot[sp + 1] = 2 * me
            dep[sp + 1] = d + 1
            sp += 2
    return count, max_depth
