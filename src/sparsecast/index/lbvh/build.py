"""LBVH over bricks (Zellmann, Hellmann & Lang, PacificVis 2019).

The domain is cut into bricks of ``brick`` x ``brick`` x ``brick`` voxel cells
(brick ``b`` spans index coordinates ``[b*B, min((b+1)*B, n-1)]`` on each axis).
Bricks are classified empty / non-empty for the TF (their value ranges include a
one-voxel apron, so the classification is conservative), the non-empty ones are
compacted, sorted along a Morton curve and organised into a binary radix tree by
Karras' (2012) fully parallel algorithm; a bottom-up refit gives every node its
box. Each phase is timed on its own (``build_phases``, milliseconds):

``voting``      classification of every brick: from the volume's cached brick
                min/max and an O(1) TF range query per brick (``voting="bricks"``,
                O(#bricks)), or from a fresh parallel min/max pass over the voxels
                (``voting="voxels"``, the paper's per-voxel pass; same answer);
``compaction``  prefix sum over the occupancy -> ids of the non-empty bricks;
``morton``      30-bit Morton codes of the brick coordinates (63-bit when a volume
                has more than 1024 bricks along an axis);
``sort``        sort by code (LSD radix sort or NumPy's stable argsort, the faster);
``hierarchy``   Karras' radix tree, one parallel task per inner node;
``refit``       bottom-up AABBs in brick coordinates (one serial O(n) post-order
                walk: Numba offers no CPU atomics for the paper's per-node
                arrival counters, and at 10^3..10^5 leaves this takes < 1 ms);
``layout``      depth-first node order, index-space boxes, optional pruning.

Arrays (traversed by :mod:`.traversal`)
---------------------------------------
child : (m, 2) int32
    Children of node ``i`` (``-1, -1`` for a leaf). Node 0 is the root; nodes are
    in depth-first pre-order (a left child directly follows its parent). ``m`` is
    0 when no brick is non-empty, else ``2L - 1`` for ``L`` leaves.
box : (m, 6) float64
    Node AABB in index space, ``lo x, y, z, hi x, y, z``; integer-valued, the exact
    union of its bricks' boxes.
leaf_first, leaf_count : (m,) int32
    Range of ``bricks`` under each node (a node covers a contiguous run of the
    Morton-sorted bricks).
bricks : (n,) int64
    Flat ids (C order over the ``(nbz, nby, nbx)`` brick grid) of the non-empty
    bricks, Morton-sorted.
brick : int
    Voxel cells per brick edge.

Pruning (``prune=f``, ``0 < f <= 1``): a subtree whose fill ratio (non-empty
bricks under it / bricks its box spans) is at least ``f`` becomes one leaf
covering its whole box. Such a box can overlap the boxes of other leaves (LBVH
node boxes may overlap even though bricks do not); the renderer stays exact
because it visits leaves in non-decreasing order of ray entry ``t`` and marches
each with the shared ``k_next`` de-duplication, which takes every lattice sample
in the union of the leaves' intervals exactly once and in increasing order (see
:mod:`.traversal`). Pruning only adds samples in empty space.
"""

from __future__ import annotations

import time

import numpy as np

from ..._util.checks import as_float, as_int, one_of
from ...kernels.bricks import brick_minmax
from ..base import SpatialIndex, View
from ..registry import register_index
from . import construct as K
from .traversal import LbvhRecord

__all__ = ["LBVH"]

VOTING = ("bricks", "voxels")
#: sort used for the Morton codes: "radix" (LSD radix sort) or "argsort" (NumPy stable)
SORT = "radix"  # measured: 2-4x faster than argsort up to 10^5..10^6 keys, on par at 2*10^6


def _check_options(brick, prune, voting):
    b = as_int(brick, "brick", 2, 64, expected="an integer in 2..64 (voxels per edge)")
    if prune is not None:
        prune = as_float(prune, "prune", 0.0, 1.0, lo_open=True, expected="None or a fill ratio in (0, 1]")
    return b, prune, one_of(voting, "voting", VOTING, expected=f"one of {VOTING}")


def brick_grid_shape(shape, brick: int) -> tuple[int, int, int]:
    """Brick counts ``(nbz, nby, nbx)`` of a ``(nz, ny, nx)`` volume (as ``Volume.brick_stats``)."""
    return tuple(max(1, -(-(n - 1) // brick)) for n in shape)  # type: ignore[return-value]


def vote_bricks(volume, tf, brick: int) -> np.ndarray:
    """Brick occupancy (flat bool) from the volume's cached brick min/max: O(#bricks).

    ``tf.classify_bricks(volume, brick)``: the TF range query on the brick min/max
    (refined by per-brick label sets for a label TF).
    """
    return tf.classify_bricks(volume, brick).ravel()


def vote_voxels(volume, tf, brick: int) -> np.ndarray:
    """Brick occupancy (flat bool) from a fresh parallel pass over the voxels.

    The per-voxel vote of the paper, made conservative for trilinear samples: each
    brick's apron min/max is reduced from its voxels (not from the cache) and then
    classified with the TF range query, so the answer equals :func:`vote_bricks`.
    (Voting "visible" per voxel value alone would not be conservative: a sample
    interpolated between two voxels can hit a narrow TF peak that neither value
    does.) A label TF refines it with the volume's per-brick label sets, as there.
    """
    voxels = volume.voxels(tf)
    if not isinstance(voxels, np.ndarray):
        # A bricked volume's statistics were reduced from its voxels when it was
        # stored; a fresh pass would read the source again for the same answer.
        return vote_bricks(volume, tf, brick)
    nbz, nby, nbx = brick_grid_shape(volume.shape, brick)
    vmin = np.empty((nbz, nby, nbx), np.float64)
    vmax = np.empty((nbz, nby, nbx), np.float64)
    brick_minmax(voxels, brick, nbz, nby, nbx, vmin, vmax)
    occ = K.classify_bricks(tf.prefix, float(tf.value_range[0]), tf.scale, vmin.ravel(), vmax.ravel())
    return tf.refine_bricks(volume, brick, occ.reshape(nbz, nby, nbx)).ravel()


@register_index
class LBVH(SpatialIndex):
    """Linear BVH over the non-empty bricks; see the module docstring for the arrays.

    Parameters
    ----------
    volume, tf
        What to index.
    brick : int
        Voxel cells per brick edge (default 8).
    prune : float or None
        Collapse subtrees whose fill ratio is at least this into one leaf. The
        default 1.0 collapses only completely full subtrees: the same samples, fewer
        leaves (it removes most of the overhead when nothing is empty). None keeps
        one leaf per brick.
    voting : {"bricks", "voxels"}
        Classify bricks from the cached brick min/max (default) or from a pass over
        the voxels.
    """

    name = "lbvh"

    def __init__(self, volume, tf, brick: int = 8, prune: float | None = 1.0, voting: str = "bricks") -> None:
        super().__init__(volume, tf)
        self.brick, self.prune, self.voting = _check_options(brick, prune, voting)
        B = self.brick
        nz, ny, nx = volume.shape
        nbz, nby, nbx = brick_grid_shape(volume.shape, B)
        self.grid_shape = (nbz, nby, nbx)
        ph = self.build_phases
        clock = time.perf_counter

        t0 = clock()
        occ = vote_bricks(volume, tf, B) if self.voting == "bricks" else vote_voxels(volume, tf, B)
        t1 = clock()
        ph["voting"] = (t1 - t0) * 1e3

        ids = K.compact(occ)
        t2 = clock()
        ph["compaction"] = (t2 - t1) * 1e3
        n = ids.shape[0]
        self.wide_codes = max(nbz, nby, nbx) > K.MORTON30_MAX

        codes = K.morton_codes(ids, nby, nbx, self.wide_codes)
        t3 = clock()
        ph["morton"] = (t3 - t2) * 1e3

        perm = K.radix_argsort(codes) if SORT == "radix" else np.argsort(codes, kind="stable")
        self.bricks = ids[perm]
        self.codes = codes[perm]
        t4 = clock()
        ph["sort"] = (t4 - t3) * 1e3

        m = max(2 * n - 1, 0)
        left = np.empty(m, np.int64)
        right = np.empty(m, np.int64)
        parent = np.empty(m, np.int64)
        first = np.empty(m, np.int64)
        last = np.empty(m, np.int64)
        if n:
            K.karras_hierarchy(self.codes, left, right, parent, first, last)
        t5 = clock()
        ph["hierarchy"] = (t5 - t4) * 1e3

        plane = nby * nbx
        coords = np.empty((n, 3), np.int64)
        bz = self.bricks // plane
        r = self.bricks - bz * plane
        coords[:, 2] = bz
        coords[:, 1] = r // nbx
        coords[:, 0] = r - coords[:, 1] * nbx
        bbox = np.empty((m, 6), np.int64)
        node_depth = np.zeros(m, np.int64)
        self.depth = int(K.refit(left, right, coords, bbox, node_depth)) if n else 0
        t6 = clock()
        ph["refit"] = (t6 - t5) * 1e3

        child = np.empty((m, 2), np.int32)
        box = np.empty((m, 6), np.float64)
        leaf_first = np.empty(m, np.int32)
        leaf_count = np.empty(m, np.int32)
        count = 0
        if n:
            count, self.depth = K.layout(left, right, bbox, first, last, self.prune or 0.0, B,
                                         np.array([nx, ny, nz], np.int64), child, box, leaf_first,
                                         leaf_count)
        self.child = child[:count]
        self.box = box[:count]
        self.leaf_first = leaf_first[:count]
        self.leaf_count = leaf_count[:count]
        ph["layout"] = (clock() - t6) * 1e3
        self.nbytes = int(self.child.nbytes + self.box.nbytes + self.leaf_first.nbytes
                          + self.leaf_count.nbytes + self.bricks.nbytes)

    def traversal_record(self, view: View) -> LbvhRecord:
        return LbvhRecord(self.child, self.box)

    # -- derived facts ----------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return int(self.child.shape[0])

    @property
    def n_leaves(self) -> int:
        return int((self.child[:, 0] < 0).sum())

    @property
    def n_bricks(self) -> int:
        """Non-empty bricks."""
        return int(self.bricks.shape[0])

    def occupancy(self) -> float:
        return self.n_bricks / float(np.prod(self.grid_shape))

    def stats(self) -> dict:
        s = super().stats()
        s.update(brick=self.brick, prune=self.prune, voting=self.voting, bricks=self.n_bricks,
                 occupancy=self.occupancy(), leaves=self.n_leaves,
                 inner_nodes=self.n_nodes - self.n_leaves, depth=self.depth,
                 morton_bits=63 if self.wide_codes else 30)
        return s

