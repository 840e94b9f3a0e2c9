"""Binned-SAH BVH construction over primitive boxes (Numba kernels, ``nogil``).

Why this builder: a top-down binned SAH (Wald 2007) costs O(n log n) with a small
constant when binning and partitioning run compiled. Every node bins its
primitives' centroids along all three axes (16 bins by default) and takes the
cheapest border; the split then partitions the primitive references *with their
boxes* in place (Embree's PrimRef arrays), so each pass over a node reads
memory in order instead of gathering boxes through an index.

Parallel build (the driver is :func:`.sah.build_sah`): :func:`build_range` first
splits the top of the tree on one thread until every pending node holds at most
``stop`` primitives; those nodes become tasks, and the same kernel builds each
task's subtree on a pool of threads (``nogil``), each into its own range of node
slots. The result is the **build layout**: node ``k`` has bounds
``bounds[k]`` (min, max) and either children ``first[k]`` and ``first[k] + 1``
(``count[k] == 0``) or a leaf of ``count[k]`` primitives
``ids[first[k] : first[k] + count[k]]``; slots between the tasks' ranges are
unused. :func:`flatten_binary` turns it into the compact depth-first layout the
binary traversal reads, as pbrt-v4 and madmann91/bvh separate build from
traversal layout.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: cost of one traversal step relative to one triangle test (Aila & Laine use ~1)
C_TRAVERSE = 1.0
#: floats per node on the task list: box min, max, centroid (doubled) min, max
NODE_BOX = 12


@njit(cache=True, inline="always")
def _half_area(x0, y0, z0, x1, y1, z1):
    ex, ey, ez = x1 - x0, y1 - y0, z1 - z0
    return ex * ey + ey * ez + ez * ex


@njit(cache=True, nogil=True)
def prim_refs(bmin, bmax):
    """References of ``m`` primitive boxes: ``(box (m, 6) float32 lo|hi, ids (m,) int32, root (12,) float32)``.

    ``root`` holds the union box and the bounds of the doubled centroids ``lo + hi``.
    """
    m = bmin.shape[0]
    box = np.empty((m, 6), np.float32)
    ids = np.empty(m, np.int32)
    root = np.empty(NODE_BOX, np.float32)
    for a in range(3):
        root[a] = root[6 + a] = np.inf
        root[3 + a] = root[9 + a] = -np.inf
    for p in range(m):
        ids[p] = p
        for a in range(3):
            lo, hi = np.float32(bmin[p, a]), np.float32(bmax[p, a])
            box[p, a], box[p, 3 + a] = lo, hi
            c = lo + hi
            root[a] = min(root[a], lo)
            root[3 + a] = max(root[3 + a], hi)
            root[6 + a] = min(root[6 + a], c)
            root[9 + a] = max(root[9 + a], c)
    return box, ids, root


@njit(cache=True, inline="always")
def _bin_of(c, c_lo, scale, n_bins):
    return min(max(int((c - c_lo) * scale), 0), n_bins - 1)


@njit(cache=True, inline="always")
def _ref_bounds(box, s, e, out, k):
    """Box and doubled-centroid bounds of references ``s:e`` into ``out[k]``."""
    for q in range(3):
        out[k, q] = out[k, 6 + q] = np.inf
        out[k, 3 + q] = out[k, 9 + q] = -np.inf
    for i in range(s, e):
        for q in range(3):
            lo, hi = box[i, q], box[i, 3 + q]
            out[k, q] = min(out[k, q], lo)
            out[k, 3 + q] = max(out[k, 3 + q], hi)
            out[k, 6 + q] = min(out[k, 6 + q], lo + hi)
            out[k, 9 + q] = max(out[k, 9 + q], lo + hi)


@njit(cache=True, nogil=True)
def build_range(box, ids, bounds, first, count, root, s_root, e_root, root_box, next_node, depth0,
                max_leaf, n_bins, stop, task_node, task_s, task_e, task_box, task_depth):
    """Build the subtree of node ``root`` over references ``s_root:e_root``.

    Parameters
    ----------
    box : (m, 6) float32, ids : (m,) int32
        Primitive references (:func:`prim_refs`); partitioned in place.
    bounds : (cap, 2, 3) float32, first, count : (cap,) int32
        The build layout, written for ``root`` and the nodes this call allocates,
        from slot ``next_node`` on (pairs of siblings).
    root_box : (12,) float32
        Box and doubled-centroid bounds of the root's references.
    depth0 : int
        Depth of ``root`` (the tree's root has depth 1).
    max_leaf, n_bins : int
        Nodes of at most ``max_leaf`` references become leaves; SAH bins per axis.
    stop : int
        Nodes (other than ``root``) of at most ``stop`` references and more than
        ``max_leaf`` are not built but written to the task arrays (``task_node``,
        ``task_s``, ``task_e``, ``task_depth`` (t,) int32 and ``task_box`` (t, 12));
        -1 builds everything.

    Returns
    -------
    next_node : int
        The first slot not allocated.
    max_depth : int
    n_tasks : int
    """
    n_all = e_root - s_root
    cap = n_all + 2  # pending nodes: at most one per level plus the one being split
    st_node = np.empty(cap, np.int32)
    st_s = np.empty(cap, np.int32)
    st_e = np.empty(cap, np.int32)
    st_d = np.empty(cap, np.int32)
    st_box = np.empty((cap, NODE_BOX), np.float32)
    bin_cnt = np.empty((3, n_bins), np.int32)
    bin_box = np.empty((3, n_bins, 6), np.float32)
    right_area = np.empty(n_bins)
    right_cnt = np.empty(n_bins, np.int32)
    nbx = np.empty(NODE_BOX, np.float32)  # the node being split (its stack slot is reused)
    st_node[0], st_s[0], st_e[0], st_d[0] = root, s_root, e_root, depth0
    # Element loops rather than slice assignments: a slice assignment compiles Numba's
    # shape-mismatch message with it (string formatting, 2.7 s of a cold build).
    for a in range(NODE_BOX):
        st_box[0, a] = root_box[a]
    sp = 1
    max_depth = depth0
    n_tasks = 0
    while sp > 0:
        sp -= 1
        node, s, e, d = st_node[sp], st_s[sp], st_e[sp], st_d[sp]
        for a in range(NODE_BOX):
            nbx[a] = st_box[sp, a]
        max_depth = max(max_depth, d)
        for a in range(3):
            bounds[node, 0, a] = nbx[a]
            bounds[node, 1, a] = nbx[3 + a]
        n = e - s
        if n <= max_leaf:
            first[node] = s
            count[node] = n
            continue
        if stop >= 0 and n <= stop and node != root:
            task_node[n_tasks], task_s[n_tasks], task_e[n_tasks], task_depth[n_tasks] = node, s, e, d
            for a in range(NODE_BOX):
                task_box[n_tasks, a] = nbx[a]
            n_tasks += 1
            continue
        # Bin the centroids along every axis with a non-zero extent; small nodes
        # use fewer bins (clearing and sweeping 16 bins would outweigh binning them).
        nbins = min(n_bins, max(n, 2))
        scale0 = scale1 = scale2 = 0.0
        ext0, ext1, ext2 = nbx[9] - nbx[6], nbx[10] - nbx[7], nbx[11] - nbx[8]
        if ext0 > 0:
            scale0 = nbins * (1.0 - 1e-6) / ext0
        if ext1 > 0:
            scale1 = nbins * (1.0 - 1e-6) / ext1
        if ext2 > 0:
            scale2 = nbins * (1.0 - 1e-6) / ext2
        for a in range(3):
            for b in range(nbins):
                bin_cnt[a, b] = 0
                for q in range(3):
                    bin_box[a, b, q] = np.inf
                    bin_box[a, b, 3 + q] = -np.inf
        for i in range(s, e):
            b0 = _bin_of(box[i, 0] + box[i, 3], nbx[6], scale0, nbins)
            b1 = _bin_of(box[i, 1] + box[i, 4], nbx[7], scale1, nbins)
            b2 = _bin_of(box[i, 2] + box[i, 5], nbx[8], scale2, nbins)
            bin_cnt[0, b0] += 1
            bin_cnt[1, b1] += 1
            bin_cnt[2, b2] += 1
            for q in range(3):
                lo, hi = box[i, q], box[i, 3 + q]
                bin_box[0, b0, q] = min(bin_box[0, b0, q], lo)
                bin_box[0, b0, 3 + q] = max(bin_box[0, b0, 3 + q], hi)
                bin_box[1, b1, q] = min(bin_box[1, b1, q], lo)
                bin_box[1, b1, 3 + q] = max(bin_box[1, b1, 3 + q], hi)
                bin_box[2, b2, q] = min(bin_box[2, b2, q], lo)
                bin_box[2, b2, 3 + q] = max(bin_box[2, b2, 3 + q], hi)
        best, best_a, best_b = np.inf, -1, -1
        for a in range(3):
            if nbx[9 + a] <= nbx[6 + a]:
                continue
            # Sweep from the right, then from the left, pricing each bin border.
            rl0 = rl1 = rl2 = np.inf
            rh0 = rh1 = rh2 = -np.inf
            rc = 0
            for b in range(nbins - 1, 0, -1):
                rl0 = min(rl0, bin_box[a, b, 0]); rl1 = min(rl1, bin_box[a, b, 1]); rl2 = min(rl2, bin_box[a, b, 2])
                rh0 = max(rh0, bin_box[a, b, 3]); rh1 = max(rh1, bin_box[a, b, 4]); rh2 = max(rh2, bin_box[a, b, 5])
                rc += bin_cnt[a, b]
                right_cnt[b] = rc
                right_area[b] = _half_area(rl0, rl1, rl2, rh0, rh1, rh2) if rc > 0 else 0.0
            ll0 = ll1 = ll2 = np.inf
            lh0 = lh1 = lh2 = -np.inf
            lc = 0
            for b in range(1, nbins):
                ll0 = min(ll0, bin_box[a, b - 1, 0]); ll1 = min(ll1, bin_box[a, b - 1, 1])
                ll2 = min(ll2, bin_box[a, b - 1, 2])
                lh0 = max(lh0, bin_box[a, b - 1, 3]); lh1 = max(lh1, bin_box[a, b - 1, 4])
                lh2 = max(lh2, bin_box[a, b - 1, 5])
                lc += bin_cnt[a, b - 1]
                if lc == 0 or right_cnt[b] == 0:
                    continue
                cost = _half_area(ll0, ll1, ll2, lh0, lh1, lh2) * lc + right_area[b] * right_cnt[b]
                if cost < best:
                    best, best_a, best_b = cost, a, b
        parent_area = _half_area(nbx[0], nbx[1], nbx[2], nbx[3], nbx[4], nbx[5])
        split_cost = C_TRAVERSE + best / parent_area if parent_area > 0 else np.inf
        if best_a >= 0 and split_cost >= n and n <= 4 * max_leaf:
            first[node] = s
            count[node] = n
            continue  # SAH: testing the primitives is cheaper than any split
        # Partition the references (with their boxes) in place, gathering both
        # sides' boxes and centroid bounds for their own split.
        if best_a >= 0:
            c_lo = nbx[6 + best_a]
            scale = (scale0, scale1, scale2)[best_a]
            i, j = s, e - 1
            while i <= j:
                if _bin_of(box[i, best_a] + box[i, 3 + best_a], c_lo, scale, nbins) < best_b:
                    i += 1
                else:
                    for q in range(6):
                        box[i, q], box[j, q] = box[j, q], box[i, q]
                    ids[i], ids[j] = ids[j], ids[i]
                    j -= 1
            mid = i
        else:
            mid = (s + e) // 2  # every centroid in one point: split by position in the list
        left = next_node
        next_node += 2
        first[node] = left
        count[node] = 0
        # Right child below the left one on the stack: the left subtree is built first.
        st_node[sp], st_s[sp], st_e[sp], st_d[sp] = left + 1, mid, e, d + 1
        st_node[sp + 1], st_s[sp + 1], st_e[sp + 1], st_d[sp + 1] = left, s, mid, d + 1
        _ref_bounds(box, mid, e, st_box, sp)
        _ref_bounds(box, s, mid, st_box, sp + 1)
        sp += 2
    return next_node, max_depth, n_tasks


@njit(cache=True, nogil=True)
def flatten_binary(bounds, first, count, n_nodes_max):
    """The build layout as a compact depth-first binary layout.

    Returns ``node_bounds (n, 2, 3) float32, node_child (n,) int32, node_count (n,) int32``
    in the encoding of :mod:`._bvh_kernels` (children ``node_child`` and
    ``node_child + 1``); a node's subtree follows it (its first child's subtree
    first), so a ray descending the tree reads nearby memory.
    """
    nb = np.empty((n_nodes_max, 2, 3), np.float32)
    child = np.empty(n_nodes_max, np.int32)
    cnt = np.empty(n_nodes_max, np.int32)
    st_src = np.empty(n_nodes_max + 1, np.int32)
    st_dst = np.empty(n_nodes_max + 1, np.int32)
    st_src[0], st_dst[0] = 0, 0
    sp = 1
    n = 1
    while sp > 0:
        sp -= 1
        src, dst = st_src[sp], st_dst[sp]
        nb[dst] = bounds[src]
        if count[src] > 0 or first[src] < 0:
            child[dst], cnt[dst] = first[src], count[src]
            continue
        child[dst], cnt[dst] = n, 0
        c = first[src]
        st_src[sp], st_dst[sp] = c + 1, n + 1
        st_src[sp + 1], st_dst[sp + 1] = c, n
        sp += 2
        n += 2
    return nb[:n].copy(), child[:n].copy(), cnt[:n].copy()
