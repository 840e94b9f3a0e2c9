"""k-d trees over the occupied cells, built with partial summed-volume tables.

Vidal, Mei & Decaudin (JGT 2008) build a k-d tree whose leaves are tight boxes
around the non-empty voxels; Zellmann, Schulze & Lang (EGPGV 2018) make the
construction fast enough to redo on every TF change with summed-volume tables
(SVTs) per brick. This module does the same on the CPU:

1. ``classify``: occupancy of every *cell* (unit cube between voxels) from the TF
   range query over its own eight corners (``apron=True``: plus a one-voxel apron,
   as the hybrids' grids need); bricks that the per-volume 8^3 brick ranges
   classify empty are skipped without reading voxels (see :mod:`.occupancy`).
2. ``svt``: per 32^3 brick the occupied count, tight box and, for non-empty bricks
   only, a partial SVT (parallel over bricks).
3. ``split``: greedy top-down construction minimising the summed volume of the
   children's tight boxes; children are shrunk to their tight boxes.

``kdtree-shallow`` applies Vidal's halting rule (both children >= 10 % of the
root's volume and a smaller summed volume); ``kdtree-deep`` splits down to leaves
of ``min_leaf`` (:data:`MIN_LEAF`, 2) cells on the split axis.

Arrays (traversed by :mod:`.traversal`, and by the hybrid grids)
----------------------------------------------------------------
node_box : (n, 6) int32
    Tight box ``(x0, y0, z0, x1, y1, z1)`` of each node in cells, half-open; cell
    ``c`` spans index coordinates ``[c, c + 1]``, so the node covers the
    index-space box ``[x0, min(x1, nx-1)]`` etc.
node_axis : (n,) int8
    Split axis (0 = x, 1 = y, 2 = z), -1 for leaves.
node_split : (n,) int32
    Split plane (index coordinate); left child ``<=``, right child ``>=``.
node_child : (n,) int32
    First child; the second is ``node_child + 1`` (-1 for leaves).
leaf_lo, leaf_hi : (nleaves, 3) float64
    Index-space boxes of the leaves (x, y, z), in node order.
node_leaf : (n,) int32
    Row of a leaf node in ``leaf_lo``/``leaf_hi`` (-1 for inner nodes).

Leaves are disjoint (children lie on either side of their parent's plane) and
cover every occupied cell. An empty classification gives a tree with no nodes.

Exactness without the apron
---------------------------
A trilinear sample reads the eight corners of the cell that contains its rounded
index-space position ``x`` (the sampler's ``floor``, clamped: the closed cell box
holds ``x``, up to an ulp at the volume's faces), and its value lies in their range
up to the rounding :data:`~sparsecast.kernels.classify.SPAN_MARGIN` absorbs. So a
sample of non-zero opacity has ``x`` inside an occupied cell, hence inside a leaf.
Its ``t`` must then lie inside that leaf's ray interval. ``x = o + t d`` is rounded
by a few ulps of the coordinates, which in ``t`` is ``ulps / |d_axis|``: without
bound for a grazing ray, so no widening of ``t`` alone can cover it. Growing every
box by :data:`BOX_MARGIN` voxels (1e-6, against rounding of ~1e-13 voxels for
volumes up to 10^5 voxels an edge) puts such a ``t`` strictly inside the grown slab,
by ``(BOX_MARGIN - ulps) / |d_axis|``, far above the rounding of the slab test
itself; an axis-parallel ray (``d_axis == 0``) has ``x_axis == o_axis`` exactly and
is tested against the grown planes directly. The apron, the conservative answer of
earlier versions, made the occupied set 2.2-2.9x larger on the shared CT / MR
volumes at a 35 % isovalue. Grown boxes add only samples of zero opacity or samples
the naive marcher takes too, which changes no float.
"""

from __future__ import annotations

import time

import numpy as np

from ..._util.checks import as_float, as_int
from ..base import SpatialIndex, View
from ..registry import register_index
from . import occupancy
from .split import build_tree
from .traversal import TILE_LEAVES, KdListRecord, KdStackRecord

__all__ = ["KdTree", "ShallowKdTree", "DeepKdTree", "CellOccupancy", "cell_occupancy", "BOX_MARGIN", "MIN_LEAF"]

#: growth of every node and leaf box on each side, in voxels (see "Exactness")
BOX_MARGIN = 1e-6
#: the deep tree's default ``min_leaf``. Measured (``sparsecast bench``, 9 shared CT / MR /
#: density volumes, 2 views, 512^2 and 1024^2, one interleaved run, 2026-12-06): against 4
#: (with 96-leaf tile lists), the samples fall from 1.39-7.16x the oracle to 1.31-6.30x
#: (bonsai 1.97 -> 1.62, headsq 2.18 -> 1.87, aneurism 4.05 -> 2.72); frames 1.02-1.15x
#: faster on aneurism, avm-cta, chest-ct, density-1jzv and headsq, within 3 % on the tooth
#: and neghip, but 0.82-0.97x on bonsai and 0.84-0.99x on mni152 (their trees hold 2.7-3x
#: the leaves, and each tile walks and clips more of them); rebuilds 1.15-1.6x longer.
#: At 8, 1.8-5.1x the oracle and slower frames everywhere.
MIN_LEAF = 2


class CellOccupancy:
    """Cell occupancy of a volume for a TF, with its partial SVTs.

    Attributes: ``occ_b`` (n, 8, 8, 8) uint8, the cells of the 8^3 bricks that
    may be non-empty, with ``bmap`` (brick -> row, -1: all empty); ``bcount``,
    ``bbox``, ``bslot`` (per 32^3 brick) and ``svt`` (n_nonempty, 33, 33, 33)
    uint16; ``phases`` (ms of ``classify`` and ``svt``). ``occ`` expands the
    occupancy to a dense (ncz, ncy, ncx) array on demand (tests, tools).
    """

    def __init__(self, volume, tf, apron: bool = True) -> None:
        self.phases: dict[str, float] = {}
        self.apron = bool(apron)
        nz, ny, nx = volume.shape
        ncz, ncy, ncx = (max(n - 1, 1) for n in (nz, ny, nx))
        t0 = time.perf_counter()
        stats = volume.brick_stats(occupancy.CLASSIFY_BRICK)  # cached per volume
        flags = tf.classify_bricks(volume, occupancy.CLASSIFY_BRICK)  # 8^3 bricks that may hold occupied cells
        bricks = np.flatnonzero(flags)
        bmap = np.full(flags.shape, -1, np.int32)
        bmap.ravel()[bricks] = np.arange(bricks.size, dtype=np.int32)
        occ = np.zeros((bricks.size, 8, 8, 8), np.uint8)
        occupancy.classify_cells(volume.voxels(tf), bricks, stats.vmin.ravel()[bricks], stats.vmax.ravel()[bricks],
                         tf.prefix, float(tf.value_range[0]), float(tf.scale), ncz, ncy, ncx,
                         int(self.apron), occ)
        self.phases["classify"] = (time.perf_counter() - t0) * 1e3
        self._build_svts((ncz, ncy, ncx), bmap, occ)

    @classmethod
    def from_occupancy(cls, occ: np.ndarray) -> "CellOccupancy":
        """SVTs of a given dense (ncz, ncy, ncx) cell occupancy (for tests and tools)."""
        self = cls.__new__(cls)
        self.phases = {}
        occ = np.asarray(occ, dtype=np.uint8)
        shape = occ.shape
        nb = tuple(-(-n // 8) for n in shape)
        pad = np.zeros(tuple(8 * m for m in nb), np.uint8)
        pad[: shape[0], : shape[1], : shape[2]] = occ
        blocks = pad.reshape(nb[0], 8, nb[1], 8, nb[2], 8).transpose(0, 2, 4, 1, 3, 5).reshape(-1, 8, 8, 8)
        keep = np.flatnonzero(blocks.reshape(blocks.shape[0], -1).any(axis=1))
        bmap = np.full(nb, -1, np.int32)
        bmap.ravel()[keep] = np.arange(keep.size, dtype=np.int32)
        self._build_svts(shape, bmap, np.ascontiguousarray(blocks[keep]))
        return self

    def _build_svts(self, shape, bmap: np.ndarray, occ_b: np.ndarray) -> None:
        """Cells stored per 8^3 brick: ``occ_b[bmap[bz, by, bx]]`` (-1: all empty)."""
        self._shape = tuple(int(n) for n in shape)
        self.bmap = bmap
        self.occ_b = occ_b
        t1 = time.perf_counter()
        S = occupancy.SVT_BRICK
        nb = tuple(-(-n // S) for n in shape)
        self.bcount = np.empty(nb, np.int64)
        self.bbox = np.empty(nb + (6,), np.int64)
        occupancy.brick_counts(bmap, occ_b, *self._shape, self.bcount, self.bbox)
        nonempty = self.bcount > 0
        self.bslot = np.full(nb, -1, np.int64)
        self.bslot[nonempty] = np.arange(int(nonempty.sum()))
        self.svt = np.empty((int(nonempty.sum()), S + 1, S + 1, S + 1), np.uint16)
        occupancy.build_svts(bmap, occ_b, self.bslot, self.svt)
        self.phases["svt"] = (time.perf_counter() - t1) * 1e3
        self.n_occupied = int(self.bcount.sum())

    @property
    def occ(self) -> np.ndarray:
        """Dense (ncz, ncy, ncx) uint8 occupancy (built on demand; for tests and tools)."""
        nb = self.bmap.shape
        dense = np.zeros((nb[0], nb[1], nb[2], 8, 8, 8), np.uint8)
        rows = self.bmap >= 0
        dense[rows] = self.occ_b[self.bmap[rows]]
        dense = dense.transpose(0, 3, 1, 4, 2, 5).reshape(nb[0] * 8, nb[1] * 8, nb[2] * 8)
        ncz, ncy, ncx = self._shape
        return np.ascontiguousarray(dense[:ncz, :ncy, :ncx])

    @property
    def shape(self):
        return self._shape

    @property
    def svt_bytes(self) -> int:
        return int(self.svt.nbytes + self.bcount.nbytes + self.bbox.nbytes + self.bslot.nbytes
                   + self.bmap.nbytes + self.occ_b.nbytes)

    def root_box(self) -> np.ndarray | None:
        """Tight box of all occupied cells, or None when there are none."""
        ncz, ncy, ncx = self._shape
        out = np.empty(6, np.int64)
        q = np.array([0, 0, 0, ncx, ncy, ncz], np.int64)
        if not occupancy.tight_box(self.svt, self.bslot, self.bcount, self.bbox, q, out, np.empty(6, np.int64)):
            return None
        return out

    def tight(self, box) -> np.ndarray | None:
        """Tight box of the occupied cells in ``box`` (6 ints, half-open), or None."""
        out = np.empty(6, np.int64)
        q = np.asarray(box, np.int64)
        if not occupancy.tight_box(self.svt, self.bslot, self.bcount, self.bbox, q, out, np.empty(6, np.int64)):
            return None
        return out

    def count(self, box) -> int:
        return int(occupancy.box_count(self.svt, self.bslot, self.bcount, self.bbox, np.asarray(box, np.int64)))


def cell_occupancy(volume, tf, apron: bool = True) -> CellOccupancy:
    return CellOccupancy(volume, tf, apron)


class KdTree(SpatialIndex):
    """Common part of the shallow and deep k-d trees (see the module docstring).

    Parameters
    ----------
    volume, tf
        What to index.
    bins : int
        Candidate planes per axis for nodes wider than ``bins`` at depth <
        ``bin_levels`` (default 32; 0: every cell boundary everywhere, the full
        greedy sweep). Binning makes a sweep O(bins) tight-box queries instead of
        O(extent); on the demo the leaves' summed volume stays within 1 % of the
        full sweep's.
    bin_levels : int
        Levels that use binned candidates (default 64: every node wider than ``bins``).
    min_frac : float
        Shallow trees: smallest leaf volume as a fraction of the root's (0.1).
    min_leaf : int
        Deep trees: cells a split plane leaves on either side, at least
        (:data:`MIN_LEAF`).
    apron : bool, optional
        Classify cells with the one-voxel apron (default: the class's ``apron``,
        False for the k-d trees; see "Exactness without the apron").
    """

    deep: bool = False
    #: classify cells with the one-voxel apron (see the module docstring, "Exactness")
    apron: bool = False

    def __init__(self, volume, tf, bins: int = 32, bin_levels: int = 64,
                 min_frac: float = 0.1, min_leaf: int = MIN_LEAF, apron: bool | None = None) -> None:
        super().__init__(volume, tf)
        if apron is not None:
            self.apron = bool(apron)
        self.bins = as_int(bins, "bins", lo=0)
        self.bin_levels = as_int(bin_levels, "bin_levels", lo=0)
        self.min_leaf = as_int(min_leaf, "min_leaf", lo=1)
        self.min_frac = as_float(min_frac, "min_frac", 0.0, 1.0, hi_open=True)
        self.cells = CellOccupancy(volume, tf, self.apron)
        self.build_phases.update(self.cells.phases)
        t0 = time.perf_counter()
        self._build_tree()
        self.build_phases["split"] = (time.perf_counter() - t0) * 1e3
        self._finish()

    def _build_tree(self) -> None:
        c = self.cells
        root = c.root_box()
        if root is None:
            self.node_box = np.zeros((0, 6), np.int32)
            self.node_axis = np.zeros(0, np.int8)
            self.node_split = np.zeros(0, np.int32)
            self.node_child = np.zeros(0, np.int32)
            self.node_depth = np.zeros(0, np.int32)
            return
        cap = 64 if not self.deep else max(256, 4 * c.n_occupied // (self.min_leaf ** 2) + 64)
        while True:
            box = np.empty((cap, 6), np.int64)
            axis = np.empty(cap, np.int8)
            split = np.empty(cap, np.int64)
            child = np.empty(cap, np.int64)
            depth = np.empty(cap, np.int64)
            n = build_tree(c.svt, c.bslot, c.bcount, c.bbox, root, self.deep, self.min_frac,
                             self.min_leaf, self.bins, self.bin_levels, cap, box, axis, split, child, depth)
            if n >= 0:
                break
            cap *= 4
        self.node_box = box[:n].astype(np.int32)
        self.node_axis = axis[:n].copy()
        self.node_split = split[:n].astype(np.int32)
        self.node_child = child[:n].astype(np.int32)
        self.node_depth = depth[:n].astype(np.int32)

    def _finish(self) -> None:
        nz, ny, nx = self.volume.shape
        top = np.array([nx - 1, ny - 1, nz - 1], np.float64)
        leaves = np.flatnonzero(self.node_axis < 0)
        self.node_leaf = np.full(self.node_axis.shape[0], -1, np.int32)
        self.node_leaf[leaves] = np.arange(leaves.size, dtype=np.int32)
        # Index-space boxes, grown by BOX_MARGIN so that a sample whose rounded
        # position lies in an occupied cell is inside its leaf's ray interval
        # whatever the ray's direction (see the module docstring, "Exactness").
        b = self.node_box[leaves].astype(np.float64)
        self.leaf_lo = np.ascontiguousarray(np.minimum(b[:, 0:3], top) - BOX_MARGIN)
        self.leaf_hi = np.ascontiguousarray(np.minimum(b[:, 3:6], top) + BOX_MARGIN)
        # Index-space boxes of all nodes, for the deep tree's per-ray traversal.
        nb = self.node_box.astype(np.float64)
        self.node_lo = np.ascontiguousarray(np.minimum(nb[:, 0:3], top) - BOX_MARGIN)
        self.node_hi = np.ascontiguousarray(np.minimum(nb[:, 3:6], top) + BOX_MARGIN)
        self.nbytes = int(sum(a.nbytes for a in (self.node_box, self.node_axis, self.node_split,
                                                 self.node_child, self.leaf_lo, self.leaf_hi,
                                                 self.node_leaf)))

    # -- queries ---------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return int(self.node_axis.shape[0])

    @property
    def n_leaves(self) -> int:
        return int(self.leaf_lo.shape[0])

    @property
    def height(self) -> int:
        return int(self.node_depth.max()) + 1 if self.n_nodes else 0

    def leaf_order(self, eye_or_dir: np.ndarray, perspective: bool) -> np.ndarray:
        """Leaf rows front to back for an eye (perspective) or view direction
        (orthographic), both in index space: the k-d tree's visibility order."""
        order: list[int] = []
        if self.n_nodes == 0:
            return np.zeros(0, np.int32)
        axis = self.node_axis
        split = self.node_split
        child = self.node_child
        leaf = self.node_leaf
        stack = [0]
        while stack:
            n = stack.pop()
            a = axis[n]
            if a < 0:
                order.append(int(leaf[n]))
                continue
            c = int(child[n])
            if perspective:
                left_first = eye_or_dir[a] <= split[n]
            else:
                left_first = eye_or_dir[a] >= 0.0
            if left_first:
                stack.append(c + 1)
                stack.append(c)
            else:
                stack.append(c)
                stack.append(c + 1)
        return np.asarray(order, np.int32)

    def view_leaf_order(self, view: View) -> np.ndarray:
        """:meth:`leaf_order` for a frame's view."""
        return self.leaf_order(view.eye if view.perspective else view.direction, view.perspective)

    def list_record(self, view: View) -> KdListRecord:
        """The leaves front to back for ``view`` (CPU, once per frame)."""
        return KdListRecord(self.view_leaf_order(view), self.leaf_lo, self.leaf_hi)

    def stats(self) -> dict:
        s = super().stats()
        s.update(
            height=self.height,
            nodes=self.n_nodes,
            leaves=self.n_leaves,
            svt_bytes=self.cells.svt_bytes,
            occupied_cells=self.cells.n_occupied,
            leaf_volume=int(np.prod(self.node_box[self.node_axis < 0, 3:6] - self.node_box[self.node_axis < 0, 0:3],
                                    axis=1).sum()) if self.n_nodes else 0,
            bins=self.bins,
        )
        return s


@register_index
class ShallowKdTree(KdTree):
    """Shallow k-d tree (Vidal et al. 2008 halting rule); leaves sorted per frame.

    Parameters: see :class:`KdTree`; ``min_frac`` (default 0.1) is the smallest
    leaf volume as a fraction of the root's.
    """

    name = "kdtree-shallow"
    deep = False

    def traversal_record(self, view: View) -> KdListRecord:
        return self.list_record(view)


@register_index
class DeepKdTree(KdTree):
    """Deep k-d tree down to ``min_leaf`` (default :data:`MIN_LEAF`) cells; each 8x8 tile of rays
    culls it once with the tile's frustum into a front-to-back leaf list, and its
    rays walk that list (a tile whose frustum meets more than ``tile_leaves``
    leaves traverses the tree per ray).

    Parameters: see :class:`KdTree`; ``tile_leaves`` (default
    :data:`~.traversal.TILE_LEAVES`, 0: always per ray).
    """

    name = "kdtree-deep"
    deep = True

    def __init__(self, volume, tf, tile_leaves: int = TILE_LEAVES, **options) -> None:
        self.tile_leaves = as_int(tile_leaves, "tile_leaves", lo=0, hi=4096)
        super().__init__(volume, tf, **options)

    def traversal_record(self, view: View) -> KdStackRecord:
        return KdStackRecord(self.node_axis, self.node_child, self.node_lo, self.node_hi,
                             2 * max(self.height, 1) + 4, self.tile_leaves)
