"""Collapse of a binary build tree into the 4-wide traversal layout (Numba).

Which binary nodes become wide nodes, which become leaves and which are opened
into their parent is chosen by the SAH, optimally for the given binary tree
(the dynamic programme of Ylitie, Karras & Laine 2017, "Efficient incoherent
ray traversal on GPUs through compressed wide BVHs", for width 4). Bottom-up,
``cost(n, i)`` is the least SAH cost of the subtree of ``n`` as a forest of at
most ``i`` roots: one root is a leaf (``C_PACKET`` per packet of four
triangles, allowed up to ``max_leaf_tris`` triangles) or a wide node
(``C_NODE`` plus the best split of four slots between its binary children);
each term is weighted by the root's surface area. A greedy collapse that opens
the largest child first (Wald et al. 2008) leaves the nodes above two small
leaves half empty (measured: 45 % of the wide nodes had two children); here
such leaves merge into one packet and the slots go where the SAH gains most.
Layout of :mod:`._wide_kernels`:

- ``box`` (n, 6, 4) float32: row ``r`` of node ``k`` holds coordinate ``r`` of
  its four children's boxes (rows 0-2 the min corner x, y, z, rows 3-5 the max
  corner), so one slab test over a row reads four consecutive floats; an unused
  slot has the empty box ``min = +inf, max = -inf``, which no ray enters;
- ``child`` (n, 4) int32: a wide node (``>= 0``) or a leaf, coded
  ``-1 - (first_packet << LEAF_SHIFT | (n_packets - 1))``;
- ``tri4`` (p, 9, 4) float32: packets of four triangles, row ``3 v + a`` holding
  coordinate ``a`` of vertex ``v`` of each lane (Embree's Triangle4v), so the
  triangle test runs over four lanes at once; a leaf of ``n`` triangles takes
  ``ceil(n / 4)`` packets, padding lanes are the degenerate triangle at the
  origin (no ray hits it) with face -1;
- ``face4`` (p, 4) int32: the mesh face of each lane.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: bits of a leaf code that hold its packet count minus one (leaves of up to 64 packets)
LEAF_SHIFT = 6
#: SAH cost of visiting a wide node (four box tests, the stack), and of one packet's
#: four triangle tests: measured in-process on bunny, beast and dragon (1 thread,
#: interleaved), c_packet 1.5 -> 0.35 cut the nodes 2.5x and sped diffuse rays up
#: 4-20 % (the vector triangle test is cheap next to a node's memory and branches)
C_NODE, C_PACKET = 1.0, 0.35
#: inner nodes of at most this many triangles may become one leaf (four packets)
MAX_LEAF_TRIS = 16


@njit(cache=True, inline="always")
def _area(bounds, k):
    ex = bounds[k, 1, 0] - bounds[k, 0, 0]
    ey = bounds[k, 1, 1] - bounds[k, 0, 1]
    ez = bounds[k, 1, 2] - bounds[k, 0, 2]
    return ex * ey + ey * ez + ez * ex


@njit(cache=True, nogil=True)
def _plan(bounds, first, count, c_node, c_packet, max_leaf_tris):
    """The SAH dynamic programme over the binary tree (see the module docstring).

    Returns ``ntri`` (cap,) triangles under each node, ``as_leaf`` (cap,) whether a
    root at that node is a leaf, ``use`` (cap, 5) the slots ``i' <= i`` a forest of
    at most ``i`` roots really splits (1: the node is one root), ``ksplit`` (cap, 5)
    the slots of the left child in the best split of ``i`` slots, ``order`` the
    nodes in pre-order.
    """
    cap = first.shape[0]
    order = np.empty(cap, np.int32)
    stack = np.empty(cap + 1, np.int32)
    n_ord, sp = 0, 1
    stack[0] = 0
    while sp > 0:
        sp -= 1
        b = stack[sp]
        order[n_ord] = b
        n_ord += 1
        if count[b] == 0:
            stack[sp] = first[b]
            stack[sp + 1] = first[b] + 1
            sp += 2
    ntri = np.zeros(cap, np.int32)
    cost = np.zeros((cap, 5), np.float32)  # float32: 20 bytes a slot of the build tree (2 m of them)
    as_leaf = np.zeros(cap, np.bool_)
    use = np.ones((cap, 5), np.int8)
    ksplit = np.zeros((cap, 5), np.int8)
    dist = np.empty(5)
    for q in range(n_ord - 1, -1, -1):
        b = order[q]
        area = _area(bounds, b)
        if count[b] > 0:
            ntri[b] = count[b]
            as_leaf[b] = True
            c = area * c_packet * ((count[b] + 3) // 4)
            for i in range(1, 5):
                cost[b, i] = c
            continue
        lc, rc = first[b], first[b] + 1
        ntri[b] = ntri[lc] + ntri[rc]
        for j in range(2, 5):
            dist[j] = np.inf
            for k in range(1, j):
                c = cost[lc, k] + cost[rc, j - k]
                if c < dist[j]:
                    dist[j] = c
                    ksplit[b, j] = k
        c_wide = area * c_node + dist[4]
        c_leaf = area * c_packet * ((ntri[b] + 3) // 4) if ntri[b] <= max_leaf_tris else np.inf
        as_leaf[b] = c_leaf <= c_wide
        cost[b, 1] = min(c_leaf, c_wide)
        for i in range(2, 5):
            if dist[i] < cost[b, i - 1]:
                cost[b, i] = dist[i]
                use[b, i] = i
            else:
                cost[b, i] = cost[b, i - 1]
                use[b, i] = use[b, i - 1]
    return ntri, as_leaf, use, ksplit, order[:n_ord]


@njit(cache=True, nogil=True)
def collapse(bounds, first, count, ids, tris, n_wide, n_packets, c_node, c_packet, max_leaf_tris):
    """Wide layout of a binary build tree (see :mod:`._bvh_build_kernels`) over triangles ``tris`` (m, 3, 3).

    ``n_wide`` and ``n_packets`` bound the wide nodes (the binary inner nodes, or 1)
    and the packets (``sum(ceil(leaf_count / 4))`` over the binary leaves: merging
    leaves never needs more). ``c_node``, ``c_packet``: SAH costs of a wide node's
    box test and of one packet's triangle test; inner nodes of at most
    ``max_leaf_tris`` triangles may become leaves.

    Returns ``box, child, tri4, face4, depth`` (see the module docstring).
    """
    ntri, as_leaf, use, ksplit, _ = _plan(bounds, first, count, c_node, c_packet, max_leaf_tris)
    box = np.empty((n_wide, 6, 4), np.float32)
    child = np.zeros((n_wide, 4), np.int32)
    tri4 = np.zeros((n_packets, 9, 4), np.float32)
    face4 = np.full((n_packets, 4), -1, np.int32)
    st_bin = np.empty(n_wide + 1, np.int32)
    st_dst = np.empty(n_wide + 1, np.int32)
    st_depth = np.empty(n_wide + 1, np.int32)
    sub = np.empty(first.shape[0] + 1, np.int32)
    kids = np.empty(4, np.int32)
    work_b = np.empty(8, np.int32)
    work_i = np.empty(8, np.int32)
    st_bin[0], st_dst[0], st_depth[0] = 0, 0, 1
    sp = 1
    n_nodes = 1
    n_pk = 0
    depth = 1
    while sp > 0:
        sp -= 1
        b, dst, d = st_bin[sp], st_dst[sp], st_depth[sp]
        depth = max(depth, d)
        # This wide node's children: the roots of the best forest of four below b.
        n_kids = 0
        if as_leaf[b] and b == 0:
            kids[0] = b  # the whole mesh is one leaf: a root with one leaf child
            n_kids = 1
        else:
            work_b[0], work_i[0] = b, 4
            n_work = 1
            while n_work > 0:
                n_work -= 1
                c, i = work_b[n_work], work_i[n_work]
                if c != b:
                    i = use[c, i]
                if i == 1:
                    kids[n_kids] = c
                    n_kids += 1
                    continue
                k = ksplit[c, i]
                work_b[n_work], work_i[n_work] = first[c] + 1, i - k
                work_b[n_work + 1], work_i[n_work + 1] = first[c], k
                n_work += 2
        for i in range(4):
            if i >= n_kids:
                for a in range(3):
                    box[dst, a, i] = np.inf
                    box[dst, 3 + a, i] = -np.inf
                child[dst, i] = 0
                continue
            c = kids[i]
            for a in range(3):
                box[dst, a, i] = bounds[c, 0, a]
                box[dst, 3 + a, i] = bounds[c, 1, a]
            if not as_leaf[c]:
                child[dst, i] = n_nodes
                st_bin[sp], st_dst[sp], st_depth[sp] = c, n_nodes, d + 1
                sp += 1
                n_nodes += 1
                continue
            # A leaf: the triangles of every binary leaf below c, in tree order.
            npk = (ntri[c] + 3) // 4
            child[dst, i] = -1 - ((n_pk << LEAF_SHIFT) | (npk - 1))
            j = 0
            sub[0] = c
            n_sub = 1
            while n_sub > 0:
                n_sub -= 1
                e = sub[n_sub]
                if count[e] == 0:
                    sub[n_sub], sub[n_sub + 1] = first[e] + 1, first[e]
                    n_sub += 2
                    continue
                for q in range(count[e]):
                    p, lane = n_pk + j // 4, j % 4
                    tri = ids[first[e] + q]
                    face4[p, lane] = tri
                    for v in range(3):
                        for a in range(3):
                            tri4[p, 3 * v + a, lane] = tris[tri, v, a]
                    j += 1
            n_pk += npk
    return box[:n_nodes].copy(), child[:n_nodes].copy(), tri4[:n_pk].copy(), face4[:n_pk].copy(), depth
