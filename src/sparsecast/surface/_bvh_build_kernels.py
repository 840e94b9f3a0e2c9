"""Binned-SAH BVH construction over primitive boxes (Numba, one core).

Why this builder: a top-down binned SAH (Wald 2007, 16 bins along the longest
centroid axis) costs O(n log n) with a small constant when the per-node binning
and in-place partition run compiled; on 1 M triangles it finishes in about a
second on one core, inside the 3 s budget without the complexity of a parallel
task scheduler or an LBVH + treelet pass. The same function builds the triangle
subtrees of the hybrid RBVH.

Output layout (flattened, as in tinybvh / madmann91 bvh): node ``k`` has bounds
``node_bounds[k]`` (min, max) and either children ``node_child[k]`` and
``node_child[k] + 1`` (``node_count[k] == 0``) or a leaf of ``node_count[k]``
primitives ``prim_idx[node_child[k] : node_child[k] + node_count[k]]``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: cost of one traversal step relative to one triangle test (Aila & Laine use ~1)
C_TRAVERSE = 1.0


@njit(cache=True, inline="always")
def _half_area(x0, y0, z0, x1, y1, z1):
    ex, ey, ez = x1 - x0, y1 - y0, z1 - z0
    return ex * ey + ey * ez + ez * ex


@njit(cache=True)
def build_binned_sah(bmin, bmax, cent, max_leaf, n_bins):
    """Build a BVH over ``m`` primitive boxes.

    Parameters
    ----------
    bmin, bmax, cent : (m, 3) float arrays
        Primitive box corners and centroids.
    max_leaf : int
        Nodes with at most this many primitives become leaves.
    n_bins : int
        SAH bins per node.

    Returns
    -------
    node_bounds (n, 2, 3) float32, node_child (n,) int32, node_count (n,) int32,
    prim_idx (m,) int32, depth int
    """
    m = bmin.shape[0]
    idx = np.arange(m).astype(np.int32)
    cap = max(2 * m - 1, 1)
    nb = np.empty((cap, 2, 3), np.float32)
    child = np.zeros(cap, np.int32)
    count = np.zeros(cap, np.int32)
    # Pending nodes: at most one per level plus the node being split.
    st_node = np.empty(m + 2, np.int32)
    st_s = np.empty(m + 2, np.int32)
    st_e = np.empty(m + 2, np.int32)
    st_d = np.empty(m + 2, np.int32)
    bin_cnt = np.zeros(n_bins, np.int64)
    bin_lo = np.empty((n_bins, 3))
    bin_hi = np.empty((n_bins, 3))
    right_area = np.empty(n_bins)
    right_cnt = np.empty(n_bins, np.int64)
    sp = 0
    st_node[0], st_s[0], st_e[0], st_d[0] = 0, 0, m, 1
    sp = 1
    n_nodes = 1
    max_depth = 1
    while sp > 0:
        sp -= 1
        node, s, e, d = st_node[sp], st_s[sp], st_e[sp], st_d[sp]
        if d > max_depth:
            max_depth = d
        lo0 = lo1 = lo2 = np.inf
        hi0 = hi1 = hi2 = -np.inf
        c_lo0 = c_lo1 = c_lo2 = np.inf
        c_hi0 = c_hi1 = c_hi2 = -np.inf
        for i in range(s, e):
            p = idx[i]
            lo0 = min(lo0, bmin[p, 0]); lo1 = min(lo1, bmin[p, 1]); lo2 = min(lo2, bmin[p, 2])
            hi0 = max(hi0, bmax[p, 0]); hi1 = max(hi1, bmax[p, 1]); hi2 = max(hi2, bmax[p, 2])
            c_lo0 = min(c_lo0, cent[p, 0]); c_lo1 = min(c_lo1, cent[p, 1]); c_lo2 = min(c_lo2, cent[p, 2])
            c_hi0 = max(c_hi0, cent[p, 0]); c_hi1 = max(c_hi1, cent[p, 1]); c_hi2 = max(c_hi2, cent[p, 2])
        nb[node, 0, 0], nb[node, 0, 1], nb[node, 0, 2] = lo0, lo1, lo2
        nb[node, 1, 0], nb[node, 1, 1], nb[node, 1, 2] = hi0, hi1, hi2
        n = e - s
        if n <= max_leaf:
            child[node] = s
            count[node] = n
            continue
        axis = 0
        c_lo, ext = c_lo0, c_hi0 - c_lo0
        if c_hi1 - c_lo1 > ext:
            axis, c_lo, ext = 1, c_lo1, c_hi1 - c_lo1
        if c_hi2 - c_lo2 > ext:
            axis, c_lo, ext = 2, c_lo2, c_hi2 - c_lo2
        mid = (s + e) // 2
        if ext > 0.0:
            scale = n_bins / ext
            bin_cnt[:] = 0
            bin_lo[:] = np.inf
            bin_hi[:] = -np.inf
            for i in range(s, e):
                p = idx[i]
                b = min(int((cent[p, axis] - c_lo) * scale), n_bins - 1)
                bin_cnt[b] += 1
                for a in range(3):
                    bin_lo[b, a] = min(bin_lo[b, a], bmin[p, a])
                    bin_hi[b, a] = max(bin_hi[b, a], bmax[p, a])
            # Sweep from the right, then from the left, pricing each bin border.
            rl0 = rl1 = rl2 = np.inf
            rh0 = rh1 = rh2 = -np.inf
            rc = 0
            for b in range(n_bins - 1, 0, -1):
                rl0 = min(rl0, bin_lo[b, 0]); rl1 = min(rl1, bin_lo[b, 1]); rl2 = min(rl2, bin_lo[b, 2])
                rh0 = max(rh0, bin_hi[b, 0]); rh1 = max(rh1, bin_hi[b, 1]); rh2 = max(rh2, bin_hi[b, 2])
                rc += bin_cnt[b]
                right_cnt[b] = rc
                right_area[b] = _half_area(rl0, rl1, rl2, rh0, rh1, rh2) if rc > 0 else 0.0
            ll0 = ll1 = ll2 = np.inf
            lh0 = lh1 = lh2 = -np.inf
            lc = 0
            best, best_b = np.inf, -1
            for b in range(1, n_bins):
                ll0 = min(ll0, bin_lo[b - 1, 0]); ll1 = min(ll1, bin_lo[b - 1, 1]); ll2 = min(ll2, bin_lo[b - 1, 2])
                lh0 = max(lh0, bin_hi[b - 1, 0]); lh1 = max(lh1, bin_hi[b - 1, 1]); lh2 = max(lh2, bin_hi[b - 1, 2])
                lc += bin_cnt[b - 1]
                if lc == 0 or right_cnt[b] == 0:
                    continue
                cost = _half_area(ll0, ll1, ll2, lh0, lh1, lh2) * lc + right_area[b] * right_cnt[b]
                if cost < best:
                    best, best_b = cost, b
            parent_area = _half_area(lo0, lo1, lo2, hi0, hi1, hi2)
            leaf_cost = float(n)
            split_cost = C_TRAVERSE + best / parent_area if parent_area > 0 else np.inf
            if best_b < 0 or (split_cost >= leaf_cost and n <= 4 * max_leaf):
                if best_b < 0:
                    pass  # all centroids in one bin (rare): split by index below
                else:
                    child[node] = s
                    count[node] = n
                    continue
            if best_b >= 0:
                # In-place partition: bins left of best_b first.
                i, j = s, e - 1
                while i <= j:
                    p = idx[i]
                    b = min(int((cent[p, axis] - c_lo) * scale), n_bins - 1)
                    if b < best_b:
                        i += 1
                    else:
                        idx[i] = idx[j]
                        idx[j] = p
                        j -= 1
                mid = i
                if mid == s or mid == e:
                    mid = (s + e) // 2
        left = n_nodes
        n_nodes += 2
        child[node] = left
        count[node] = 0
        st_node[sp], st_s[sp], st_e[sp], st_d[sp] = left + 1, mid, e, d + 1
        sp += 1
        st_node[sp], st_s[sp], st_e[sp], st_d[sp] = left, s, mid, d + 1
        sp += 1
    return nb[:n_nodes].copy(), child[:n_nodes].copy(), count[:n_nodes].copy(), idx, max_depth
