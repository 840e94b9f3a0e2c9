"""Bottom-up node statistics and the static level-of-detail cut of a BIH (Numba kernels).

Node fields as in :mod:`.construct`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .construct import LEAF

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
