"""The 4-wide triangle BVH: the traversal layout the exact BVH of a mesh uses by default.

Built by collapsing the binary SAH build tree (:mod:`.sah`) into nodes of up to
four children, leaves and opened children chosen by the SAH
(:mod:`._wide_build_kernels`, which describes the layout), and traversed by
:mod:`._wide_kernels`: the four slab tests of a node in float32 vector lanes, the
children visited nearest first, leaves as packets of four triangles tested
together (float64 lanes) by the watertight ray-triangle test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ._wide_build_kernels import C_NODE, C_PACKET, LEAF_SHIFT, MAX_LEAF_TRIS, collapse
from ._wide_kernels import stack_size
from .sah import BuildTree

__all__ = ["WideBVH", "collapse_tree"]


@dataclass(frozen=True, eq=False)
class WideBVH:
    """A 4-wide BVH over triangles.

    Attributes
    ----------
    nodes : (n, 32) float32
        One node per 128 bytes, on 64-byte boundaries (two cache lines):
        ``nodes[k, :24]`` the children's boxes as :attr:`box` (n, 6, 4),
        ``nodes[k, 24:28]`` the int32 bits of :attr:`child` (n, 4), then padding.
    tri4 : (p, 9, 4) float32
        Leaf triangles in packets of four: ``tri4[p, 3 v + a, lane]``.
    face4 : (p, 4) int32
        Mesh face of each lane, -1 for padding.
    depth : int
        Levels of wide nodes.
    root : (2, 3) float32
        The box of every triangle.
    """

    nodes: np.ndarray
    tri4: np.ndarray
    face4: np.ndarray
    depth: int
    root: np.ndarray

    @property
    def box(self) -> np.ndarray:
        """(n, 6, 4) float32 view: ``box[k, a, c]`` is the min corner's coordinate ``a`` of
        child ``c`` of node ``k``, ``box[k, 3 + a, c]`` the max corner's (SoA)."""
        return self.nodes[:, :24].reshape(-1, 6, 4)

    @property
    def child(self) -> np.ndarray:
        """(n, 4) int32 view: node index (``>= 0``) or leaf code (:mod:`._wide_build_kernels`)."""
        return self.nodes.view(np.int32)[:, 24:28]

    def kernel_args(self) -> tuple:
        """The arrays the wide traversal kernels take: the nodes as float32 and as int32, the packets."""
        return self.nodes, self.nodes.view(np.int32), self.tri4, self.face4

    @property
    def stack_size(self) -> int:
        return stack_size(self.depth)

    @property
    def n_leaves(self) -> int:
        return int(np.count_nonzero(self.child < 0))

    def nbytes(self) -> dict[str, int]:
        """Bytes of the nodes and of the triangle packets."""
        return {"nodes": int(self.nodes.nbytes),
                "triangles": int(self.tri4.nbytes + self.face4.nbytes)}


def collapse_tree(tree: BuildTree, tris: np.ndarray, *, c_node: float = C_NODE, c_packet: float = C_PACKET,
                  max_leaf_tris: int = MAX_LEAF_TRIS) -> WideBVH:
    """The wide layout of ``tree`` (a build over ``tris`` (m, 3, 3) float32).

    ``c_node``, ``c_packet`` and ``max_leaf_tris`` steer the SAH collapse
    (:mod:`._wide_build_kernels`): the relative costs of a node's box tests and a
    packet's triangle tests, and the most triangles a leaf made of an inner node holds.
    """
    used = tree.first >= 0
    leaf = used & (tree.count > 0)
    n_packets = int(np.sum((tree.count[leaf].astype(np.int64) + 3) // 4))
    if n_packets >= 2 ** (31 - LEAF_SHIFT):
        raise ParameterError(f"mesh: {len(tris)} triangles need {n_packets} leaf packets; the wide BVH "
                             f"addresses at most {2 ** (31 - LEAF_SHIFT) - 1} (use layout='binary')")
    n_inner = int(np.count_nonzero(used & (tree.count == 0)))
    box, child, tri4, face4, depth = collapse(tree.bounds, tree.first, tree.count, tree.ids, tris,
                                              max(n_inner, 1), n_packets, float(c_node), float(c_packet),
                                              int(max_leaf_tris))
    return WideBVH(_pack_nodes(box, child), tri4, face4, int(depth), tree.bounds[0].copy())


def _pack_nodes(box: np.ndarray, child: np.ndarray) -> np.ndarray:
    """Boxes (n, 6, 4) and children (n, 4) as 128-byte nodes aligned to 64 bytes."""
    n = len(box)
    buf = np.empty(n * 32 + 16, np.float32)
    skip = (-buf.ctypes.data % 64) // 4
    nodes = buf[skip:skip + n * 32].reshape(n, 32)
    nodes[:, :24] = box.reshape(n, 24)
    nodes.view(np.int32)[:, 24:28] = child
    nodes[:, 28:] = 0.0
    return nodes
