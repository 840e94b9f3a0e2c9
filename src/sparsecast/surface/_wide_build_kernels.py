"""Collapse of a binary build tree into the 4-wide traversal layout (Numba).

Each wide node takes its binary node's two children and, while it has fewer than
four, replaces the inner child of largest surface area by that child's two
children (the greedy collapse of Wald et al. 2008 / Embree's BVH4 builder: big
boxes are the likely ones to be entered, so they are opened first). Layout of
:mod:`._wide_kernels`:

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


@njit(cache=True, inline="always")
def _area(bounds, k):
    ex = bounds[k, 1, 0] - bounds[k, 0, 0]
    ey = bounds[k, 1, 1] - bounds[k, 0, 1]
    ez = bounds[k, 1, 2] - bounds[k, 0, 2]
    return ex * ey + ey * ez + ez * ex


@njit(cache=True, nogil=True)
def collapse(bounds, first, count, ids, tris, n_wide, n_packets):
    """Wide layout of a binary build tree (see :mod:`._bvh_build_kernels`) over triangles ``tris`` (m, 3, 3).

    ``n_wide`` and ``n_packets`` bound the wide nodes (the binary inner nodes, or 1)
    and give the packets (``sum(ceil(leaf_count / 4))``).

    Returns ``box, child, tri4, face4, depth`` (see the module docstring).
    """
    box = np.empty((n_wide, 6, 4), np.float32)
    child = np.zeros((n_wide, 4), np.int32)
    tri4 = np.zeros((n_packets, 9, 4), np.float32)
    face4 = np.full((n_packets, 4), -1, np.int32)
    st_bin = np.empty(n_wide + 1, np.int32)
    st_dst = np.empty(n_wide + 1, np.int32)
    st_depth = np.empty(n_wide + 1, np.int32)
    kids = np.empty(4, np.int32)
    st_bin[0], st_dst[0], st_depth[0] = 0, 0, 1
    sp = 1
    n_nodes = 1
    n_pk = 0
    depth = 1
    while sp > 0:
        sp -= 1
        b, dst, d = st_bin[sp], st_dst[sp], st_depth[sp]
        depth = max(depth, d)
        # The children of this wide node: open the largest inner child until four.
        if count[b] > 0:
            n_kids = 1  # a binary tree that is one leaf: a root with one leaf child
            kids[0] = b
        else:
            n_kids = 2
            kids[0], kids[1] = first[b], first[b] + 1
        while n_kids < 4:
            best, best_area = -1, -1.0
            for i in range(n_kids):
                if count[kids[i]] == 0:
                    a = _area(bounds, kids[i])
                    if a > best_area:
                        best, best_area = i, a
            if best < 0:
                break
            c = kids[best]
            kids[best] = first[c]
            kids[n_kids] = first[c] + 1
            n_kids += 1
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
            if count[c] == 0:
                child[dst, i] = n_nodes
                st_bin[sp], st_dst[sp], st_depth[sp] = c, n_nodes, d + 1
                sp += 1
                n_nodes += 1
                continue
            n = count[c]
            npk = (n + 3) // 4
            child[dst, i] = -1 - ((n_pk << LEAF_SHIFT) | (npk - 1))
            for j in range(n):
                p, lane = n_pk + j // 4, j % 4
                tri = ids[first[c] + j]
                face4[p, lane] = tri
                for v in range(3):
                    for a in range(3):
                        tri4[p, 3 * v + a, lane] = tris[tri, v, a]
            n_pk += npk
    return box[:n_nodes].copy(), child[:n_nodes].copy(), tri4, face4, depth
