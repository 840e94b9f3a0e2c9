"""Collapse of the binary RBVH into the 4-wide traversal layout (Numba).

The greedy collapse of the exact BVH (:mod:`._wide_build_kernels`: each wide
node opens its inner child of largest surface area until it has four), applied
to the RBVH's binary nodes, whose leaves are tiles or runs of triangles rather
than packets. Layout (:mod:`._rbvh_wide_kernels` traverses it):

- ``box`` (n, 6, WIDTH) float32: the children's boxes in SoA rows (rows 0-2 the min
  corner x, y, z, rows 3-5 the max corner), as the exact wide BVH; an unused
  slot has the empty box ``min = +inf, max = -inf``, which no ray enters;
- ``child`` (n, WIDTH) and ``count`` (n, WIDTH) int32: the binary encoding per slot
  (:mod:`._bvh_kernels`): ``count == 0`` a wide node ``child``; ``count > 0`` a
  triangle leaf of ``count`` triangles from ``child``; ``count == TILE_LEAF`` tile
  ``child``. Leaves keep the binary tree's references, so the triangle and atlas
  arrays are shared by both layouts.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._wide_build_kernels import _area  # the same surface area as the exact BVH's collapse

#: children per wide node
WIDTH = 4


@njit(cache=True, nogil=True)
def collapse_rbvh(node_bounds, node_child, node_count):
    """Wide layout of the binary RBVH ``node_bounds (m, 2, 3), node_child (m,), node_count (m,)``.

    Returns ``box (n, 6, WIDTH) float32, child (n, 4) int32, count (n, 4) int32, depth``
    (see the module docstring); ``n`` is at most the binary inner nodes (or 1).
    """
    m = node_count.shape[0]
    n_inner = 0
    for k in range(m):
        n_inner += node_count[k] == 0
    cap = max(n_inner, 1)
    box = np.empty((cap, 6, WIDTH), np.float32)
    child = np.zeros((cap, WIDTH), np.int32)
    count = np.zeros((cap, WIDTH), np.int32)
    st_bin = np.empty(cap + 1, np.int32)
    st_dst = np.empty(cap + 1, np.int32)
    st_depth = np.empty(cap + 1, np.int32)
    kids = np.empty(WIDTH, np.int32)
    st_bin[0], st_dst[0], st_depth[0] = 0, 0, 1
    sp = 1
    n_nodes = 1
    depth = 1
    while sp > 0:
        sp -= 1
        b, dst, d = st_bin[sp], st_dst[sp], st_depth[sp]
        depth = max(depth, d)
        if node_count[b] != 0:
            n_kids = 1  # the whole tree is one leaf: a root with one leaf child
            kids[0] = b
        else:
            n_kids = 2
            kids[0], kids[1] = node_child[b], node_child[b] + 1
        while n_kids < WIDTH:
            best, best_area = -1, -1.0
            for i in range(n_kids):
                if node_count[kids[i]] == 0:
                    a = _area(node_bounds, kids[i])
                    if a > best_area:
                        best, best_area = i, a
            if best < 0:
                break
            c = kids[best]
            kids[best] = node_child[c]
            kids[n_kids] = node_child[c] + 1
            n_kids += 1
        for i in range(WIDTH):
            if i >= n_kids:
                for a in range(3):
                    box[dst, a, i] = np.inf
                    box[dst, 3 + a, i] = -np.inf
                child[dst, i] = 0
                count[dst, i] = 0
                continue
            c = kids[i]
            for a in range(3):
                box[dst, a, i] = node_bounds[c, 0, a]
                box[dst, 3 + a, i] = node_bounds[c, 1, a]
            if node_count[c] == 0:
                child[dst, i] = n_nodes
                count[dst, i] = 0
                st_bin[sp], st_dst[sp], st_depth[sp] = c, n_nodes, d + 1
                sp += 1
                n_nodes += 1
            else:
                child[dst, i] = node_child[c]
                count[dst, i] = node_count[c]
    return box[:n_nodes].copy(), child[:n_nodes].copy(), count[:n_nodes].copy(), depth
