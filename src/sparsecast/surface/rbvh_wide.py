"""The 4-wide RBVH: the traversal layout an RBVH uses by default.

The level-by-level build (:mod:`.rbvh`) makes a binary tree; collapsing it four
children per node (:mod:`._rbvh_wide_build_kernels`, which describes the layout)
halves the inner nodes a ray visits, and the traversal (:mod:`._rbvh_wide_kernels`)
tests the four child boxes of a node in one vectorisable loop, as the exact wide
BVH does. Leaves are the binary tree's: height-field tiles and runs of triangles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._rbvh_wide_build_kernels import WIDTH, collapse_rbvh
from ._rbvh_wide_kernels import stack_size

__all__ = ["WideRBVH", "collapse_binary"]


@dataclass(frozen=True, eq=False)
class WideRBVH:
    """A 4-wide RBVH.

    Attributes
    ----------
    nodes : (n, 32) float32
        One node per 128 bytes, on 64-byte boundaries: ``nodes[k, :24]`` the
        children's boxes as :attr:`box`, ``nodes[k, 24:28]`` and ``nodes[k, 28:32]``
        the int32 bits of :attr:`child` and :attr:`count`.
    depth : int
        Levels of wide nodes.
    root : (2, 3) float32
        The box of everything the tree holds.
    """

    nodes: np.ndarray
    depth: int
    root: np.ndarray

    @property
    def box(self) -> np.ndarray:
        """(n, 6, 4) float32 view: ``box[k, a, c]`` min corner coordinate ``a`` of child ``c``,
        ``box[k, 3 + a, c]`` the max corner's."""
        return self.nodes[:, :6 * WIDTH].reshape(-1, 6, WIDTH)

    @property
    def child(self) -> np.ndarray:
        """(n, 4) int32 view: wide node, first leaf triangle, or tile of each slot."""
        return self.nodes.view(np.int32)[:, 6 * WIDTH:7 * WIDTH]

    @property
    def count(self) -> np.ndarray:
        """(n, 4) int32 view: 0 (wide node), triangles (> 0) or ``TILE_LEAF`` per slot."""
        return self.nodes.view(np.int32)[:, 7 * WIDTH:]

    @property
    def stack_size(self) -> int:
        return stack_size(self.depth)

    def leaf_counts(self) -> np.ndarray:
        """``count`` of every leaf slot (non-empty slots with ``count != 0``)."""
        used = np.isfinite(self.box[:, 0, :])
        c = self.count
        return c[used & (c != 0)]

    def nbytes(self) -> int:
        return int(self.nodes.nbytes)


def collapse_binary(node_bounds: np.ndarray, node_child: np.ndarray, node_count: np.ndarray) -> WideRBVH:
    """The wide layout of a binary RBVH (``node_*`` as :class:`.index.SurfaceIndex` holds them)."""
    box, child, count, depth = collapse_rbvh(node_bounds, node_child, node_count)
    n, w = len(box), WIDTH
    # 64-byte alignment: a node is whole cache lines.
    buf = np.empty(n * 8 * w + 16, np.float32)
    skip = (-buf.ctypes.data % 64) // 4
    nodes = buf[skip:skip + n * 8 * w].reshape(n, 8 * w)
    nodes[:, :6 * w] = box.reshape(n, 6 * w)
    nodes.view(np.int32)[:, 6 * w:7 * w] = child
    nodes.view(np.int32)[:, 7 * w:] = count
    return WideRBVH(nodes, int(depth), node_bounds[0].copy())
