"""The greedy top-down split of the k-d trees (Numba kernel).

Minimises the summed volume of the children's tight boxes, queried from the
partial SVTs of :mod:`.occupancy`; children are shrunk to their tight boxes.
Boxes are ``(x0, y0, z0, x1, y1, z1)`` in cells, half-open, axis 0 = x.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .occupancy import box_count, tight_box

@njit(cache=True, inline="always")
def _vol(b):
    return np.int64(b[3] - b[0]) * np.int64(b[4] - b[1]) * np.int64(b[5] - b[2])


@njit(cache=True)
def _union(dst, i, a, j, b, k):
    """``dst[i] = a[j] U b[k]`` for boxes (rows of 6 ints)."""
    for m in range(3):
        dst[i, m] = min(a[j, m], b[k, m])
        dst[i, m + 3] = max(a[j, m + 3], b[k, m + 3])


@njit(cache=True)
def build_tree(svt, bslot, bcount, bbox, root, deep, min_frac, min_leaf, bins, bin_levels,
               cap, node_box, node_axis, node_split, node_child, node_depth):
    """Greedy top-down k-d tree over the occupied cells (see the module docstring).

    ``root`` is the tight box of all occupied cells. For every node and axis the
    node is cut into slabs (one cell thick, or ``bins`` evenly spaced slabs when
    the node is at depth < ``bin_levels`` and wider than ``bins``); one tight-box
    query per slab, then prefix and suffix unions give the tight boxes of both
    children for every candidate plane between slabs at once. The plane
    minimising the sum of the children's tight-box volumes wins, and the children
    are shrunk to their tight boxes.

    Shallow (``deep`` false, Vidal et al. 2008): a split is allowed only when both
    tight children have at least ``min_frac`` of the root's volume and the summed
    volume is smaller than the node's. Deep: planes leave at least ``min_leaf``
    cells of the node on both sides; nodes are split until no plane is possible,
    the node is fully occupied, or no plane reduces the summed volume while the
    node is at least half occupied.

    Writes the nodes (children of node ``i`` are ``node_child[i]`` and
    ``node_child[i] + 1``, leaves have ``node_axis == -1``) and returns the node
    count, or -1 when ``cap`` nodes were not enough.
    """
    for a in range(6):
        node_box[0, a] = root[a]
    node_axis[0] = -1
    node_split[0] = 0
    node_child[0] = -1
    node_depth[0] = 0
    n_nodes = 1
    root_vol = _vol(root)
    min_vol = min_frac * root_vol
    max_ext = max(root[3] - root[0], max(root[4] - root[1], root[5] - root[2]))
    stack = np.empty(cap + 2, np.int64)
    sp = 0
    stack[sp] = 0
    sp += 1
    q = np.empty(6, np.int64)
    work = np.empty(6, np.int64)
    tb = np.empty(6, np.int64)
    planes = np.empty(max_ext + 1, np.int64)
    slab = np.empty((max_ext + 1, 6), np.int64)
    has = np.empty(max_ext + 1, np.bool_)
    pre = np.empty((max_ext + 1, 6), np.int64)
    suf = np.empty((max_ext + 1, 6), np.int64)
    best_l = np.empty(6, np.int64)
    best_r = np.empty(6, np.int64)
    big = np.int64(1) << 40
    while sp > 0:
        sp -= 1
        node = stack[sp]
        box = node_box[node]
        vol = _vol(box)
        count = np.int64(0)
        if deep:
            count = box_count(svt, bslot, bcount, bbox, box)
            if count == vol:
                continue  # fully occupied: nothing to remove
        best_cost = np.int64(1) << 62
        best_axis = -1
        best_s = 0
        for ax in range(3):
            lo = box[ax]
            hi = box[ax + 3]
            ext = hi - lo
            if ext < 2 or (deep and ext < 2 * min_leaf):
                continue
            nb = ext
            if bins > 0 and node_depth[node] < bin_levels and ext > bins:
                nb = bins
            for j in range(nb + 1):
                planes[j] = lo + (j * ext) // nb
            # tight box of every slab
            for j in range(nb):
                for a in range(6):
                    q[a] = box[a]
                q[ax] = planes[j]
                q[ax + 3] = planes[j + 1]
                has[j] = tight_box(svt, bslot, bcount, bbox, q, tb, work)
                if has[j]:
                    for a in range(6):
                        slab[j, a] = tb[a]
                else:
                    for a in range(3):
                        slab[j, a] = big
                        slab[j, a + 3] = -big
            # prefix unions pre[j] = slabs 0..j-1, suffix unions suf[j] = slabs j..nb-1
            for a in range(3):
                pre[0, a] = big
                pre[0, a + 3] = -big
                suf[nb, a] = big
                suf[nb, a + 3] = -big
            for j in range(nb):
                _union(pre, j + 1, pre, j, slab, j)
            for j in range(nb - 1, -1, -1):
                _union(suf, j, suf, j + 1, slab, j)
            for j in range(1, nb):
                s = planes[j]
                if deep and (s - lo < min_leaf or hi - s < min_leaf):
                    continue
                if pre[j, 3] < pre[j, 0] or suf[j, 3] < suf[j, 0]:
                    continue  # one side empty (cannot happen for tight nodes)
                vl = np.int64(pre[j, 3] - pre[j, 0]) * (pre[j, 4] - pre[j, 1]) * (pre[j, 5] - pre[j, 2])
                vr = np.int64(suf[j, 3] - suf[j, 0]) * (suf[j, 4] - suf[j, 1]) * (suf[j, 5] - suf[j, 2])
                if not deep and (vl < min_vol or vr < min_vol):
                    continue
                cost = vl + vr
                if cost < best_cost:
                    best_cost = cost
                    best_axis = ax
                    best_s = s
                    for a in range(6):
                        best_l[a] = pre[j, a]
                        best_r[a] = suf[j, a]
        if best_axis < 0:
            continue
        if best_cost >= vol and (not deep or 2 * count >= vol):
            # no reduction: a shallow node stops; a deep one stops when at least
            # half full (a sparser one may still have holes deeper down)
            continue
        if n_nodes + 2 > cap:
            return -1
        c = n_nodes
        n_nodes += 2
        node_axis[node] = best_axis
        node_split[node] = best_s
        node_child[node] = c
        for a in range(6):
            node_box[c, a] = best_l[a]
            node_box[c + 1, a] = best_r[a]
        for k in range(2):
            node_axis[c + k] = -1
            node_split[c + k] = 0
            node_child[c + k] = -1
            node_depth[c + k] = node_depth[node] + 1
        stack[sp] = c + 1
        stack[sp + 1] = c
        sp += 2
    return n_nodes
