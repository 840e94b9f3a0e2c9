"""Bounding interval hierarchy over elements (Wächter & Keller 2006; Kinkelin's BIH-DVR).

A BIH partitions *elements* (:mod:`sparsecast.elements`: voxel cuboids, bricks,
particle spheres) rather than space. Construction (:func:`build_bih`):

1. root box = AABB of all elements;
2. a node's elements are split at the middle of its split box's longest axis by
   their AABB centres, with a quicksort-like in-place partition (Numba, explicit
   task stack) that also records the two planes: the max of the left elements and
   the min of the right ones;
3. an empty side makes no child: in the ``"basic"`` variant a single-child node
   stores the non-empty child's plane and an invalid (+-inf) plane for the empty
   one, in the ``"elaborate"`` variant the single child takes both planes (the
   elements' extent); such a node is made only where the planes actually cut the
   box, and the split box halves either way;
4. recursion ends when a node's box equals the AABB of its single element (the
   *intermediate BIH*; a leaf may also hold several identical elements).

Per-node statistics (element count and volume, mean and variance of density,
mean gradient) are combined bottom-up. :meth:`BIHTree.lod` cuts a static level of
detail (max depth, min element fill of the box, max density standard deviation);
:meth:`BIHTree.pack` serialises 8-byte nodes in pre-order or in tree chunks.

Packed node (one ``uint64``; bits, high to low)
-----------------------------------------------
inner: ``[63:62]`` axis 0-2, ``[61:32]`` 30-bit child field, ``[31:16]`` plane 1,
``[15:0]`` plane 0. Planes are 16-bit fixed point in the normalised frame of the
elements (``0x4000`` = 0, ``0xC000`` = 1; ``0x0000`` / ``0xFFFF`` = -inf / +inf, the
plane of an empty child), rounded outward so boxes only grow (error < one step =
frame / 0x8000). Two children: plane 0 bounds the left child above, plane 1 the
right child below. One child: ``(p, +inf)`` left only, ``(-inf, p)`` right only,
``(lo, hi)`` both planes (elaborate).
leaf: ``[63:62]`` = 3, ``[61:48]`` density (14 bits, [0, 1]), ``[47:0]`` gradient
z, y, x (16 bits each, ``0x8000`` = 0, ``+-0x7FFF`` = ``+-grad_scale``); particle
trees store ``[61:32]`` first element and ``[31:0]`` count instead.

Child field: pre-order layout: the left (or single) child directly follows its
parent, the field holds the right child's index, or ``i + 1`` for a single child.
Tree chunks: siblings are stored as an aligned pair (``field`` = the pair's even
index, bit 0 set for a single child), and ``chunk_depth`` levels of pairs below a
node are stored together (depth 2: a pair and its up to four children, 48 bytes,
less than a 64-byte cache line).
"""

from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass

import numpy as np

from ...elements import Elements, brick_elements, voxel_elements
from ..._util.checks import as_float, as_int, one_of, unit_float
from ...errors import ParameterError
from ..base import SpatialIndex, View
from ..registry import register_index
from . import construct, lod, pack
from .integrate import MODE_MULTI, MODE_SINGLE
from .traversal import BihApproxRecord, BihRecord, decode_inner

__all__ = ["BIH", "BIHTree", "PackedBIH", "ParticleBIH", "build_bih", "MODES", "VARIANTS", "LAYOUTS"]

MODES = ("ess", "single-sample", "multi-sample")
VARIANTS = ("basic", "elaborate")
LAYOUTS = ("preorder", "chunks")


@dataclass
class BIHTree:
    """An unpacked BIH (intermediate or LoD), nodes in depth-first pre-order.

    Attributes
    ----------
    kind : (m,) int8
        Split axis 0-2 of inner nodes, 3 for leaves.
    child : (m, 2) int64
        ``(left, right)``; a single child is ``child[:, 0]`` with ``child[:, 1] = -1``.
    plane : (m, 2) float64
        Two children: left child's upper plane, right child's lower plane; one
        child: its interval ``[plane[0], plane[1]]`` on the axis (+-inf on an open side).
    box : (m, 6) float64
        Node box as the planes cut it out (lo x, y, z, hi x, y, z).
    first, count : (m,) int64
        The node's elements: ``perm[first:first + count]``.
    depth : (m,) int64
    elem_volume, mean, var, grad : per-node statistics (sum of element volumes,
        mean and variance of density, mean gradient (m, 3)).
    perm : (n,) int64
        Element ids in tree order.
    elements : Elements
    build_ms : float
    """

    kind: np.ndarray
    child: np.ndarray
    plane: np.ndarray
    box: np.ndarray
    first: np.ndarray
    count: np.ndarray
    depth: np.ndarray
    elem_volume: np.ndarray
    mean: np.ndarray
    var: np.ndarray
    grad: np.ndarray
    perm: np.ndarray
    elements: Elements
    variant: str
    build_ms: float = 0.0

    @property
    def n_nodes(self) -> int:
        return int(self.kind.shape[0])

    @property
    def n_leaves(self) -> int:
        return int((self.kind == construct.LEAF).sum())

    @property
    def max_depth(self) -> int:
        return int(self.depth.max()) if self.n_nodes else 0

    @property
    def n_single(self) -> int:
        """Inner nodes with one child."""
        return int(((self.kind != construct.LEAF) & (self.child[:, 1] < 0)).sum())

    def stats(self) -> dict:
        m = self.n_nodes
        return {
            "elements": len(self.elements),
            "nodes": m,
            "leaves": self.n_leaves,
            "single_child_pct": 100.0 * self.n_single / m if m else 0.0,
            "max_depth": self.max_depth,
            "bytes": 8 * m,
            "build_ms": self.build_ms,
        }

    # -- level of detail ---------------------------------------------------------
    def lod(self, max_depth: int | None = None, min_fill: float = 0.75, max_std: float = 0.01) -> "BIHTree":
        """The static LoD cut: a subtree becomes one leaf (mean density and gradient)
        at ``max_depth``, or where its elements fill at least ``min_fill`` of its box
        and their density's standard deviation is at most ``max_std``."""
        md = _check_depth(max_depth)
        mf = unit_float(min_fill, "min_fill")
        ms = max_std if max_std == math.inf else as_float(max_std, "max_std", lo=0.0,
                                                           expected="a non-negative standard deviation")
        t0 = time.perf_counter()
        keep = np.empty(self.n_nodes, np.int64)
        lod.lod_cut(self.kind, self.child, self.box, self.count, self.elem_volume, self.mean, self.var * self.count,
                  md, mf, ms, keep)
        k = int((keep >= 0).sum())
        new_child = np.empty((k, 2), np.int64)
        depth = np.zeros(k, np.int64)
        old = lod.compact_cut(keep, self.child, new_child, depth)
        kind = self.kind[old].copy()
        kind[keep[old] == 1] = construct.LEAF
        out = BIHTree(kind, new_child, self.plane[old], self.box[old], self.first[old], self.count[old], depth,
                      self.elem_volume[old], self.mean[old], self.var[old], self.grad[old], self.perm,
                      self.elements, self.variant)
        out.build_ms = (time.perf_counter() - t0) * 1e3
        return out

    # -- packing -------------------------------------------------------------
    def pack(self, layout: str = "preorder", chunk_depth: int = 2) -> "PackedBIH":
        """Serialise to 8-byte nodes (see the module docstring)."""
        one_of(layout, "layout", LAYOUTS, expected=f"one of {LAYOUTS}")
        cd = as_int(chunk_depth, "chunk_depth", lo=1)
        t0 = time.perf_counter()
        m = self.n_nodes
        el = self.elements
        if m >= (1 << 29):
            raise ParameterError(f"tree: {m} nodes exceed the 30-bit child index of packed nodes")
        field_of = np.zeros(m, np.int64)
        if layout == "preorder" or m == 0:
            slot_of = np.arange(m, dtype=np.int64)
            slots = m
            if m:
                pack.preorder_fields(self.child, field_of)
        else:
            slot_of = np.empty(m, np.int64)
            slots = int(pack.chunk_layout(self.child, cd, slot_of, field_of))
        leaves = self.kind == construct.LEAF
        g = self.grad[leaves]
        grad_scale = float(np.abs(g).max()) if g.size else 1.0
        grad_scale = grad_scale if grad_scale > 0 else 1.0
        out = np.zeros(slots, np.int64)
        if m:
            pack.pack_nodes(self.kind.astype(np.int64), self.child, self.plane, self.mean, self.grad, self.first,
                         self.count, el.frame_lo, el.frame_ext, grad_scale, el.kind == "particles",
                         slot_of, field_of, out)
        root_box = np.zeros(6)
        if m:
            for a in range(3):
                root_box[a] = _dq(pack.quantize_plane(self.box[0, a], el.frame_lo[a], el.frame_ext[a], False), el, a)
                root_box[3 + a] = _dq(pack.quantize_plane(self.box[0, 3 + a], el.frame_lo[a], el.frame_ext[a], True),
                                      el, a)
        packed = PackedBIH(out.view(np.uint64), layout, cd, el.frame_lo.copy(), el.frame_ext.copy(), root_box,
                           grad_scale, self.max_depth, m)
        packed.build_ms = (time.perf_counter() - t0) * 1e3
        return packed


def _dq(q: int, el: Elements, a: int) -> float:
    return float(pack.dequantize_plane(q, el.frame_lo[a], el.frame_ext[a] / (pack.Q_ONE - pack.Q_ZERO)))


@dataclass
class PackedBIH:
    """8-byte nodes as the traversal reads them (see the module docstring).

    Attributes
    ----------
    nodes : (slots,) uint64
    layout : {"preorder", "chunks"}
    chunk_depth : int
    frame_lo, frame_ext : (3,) float64
        Normalisation frame of the planes.
    root_box : (6,) float64
        Root box, rounded outward to the plane grid.
    grad_scale : float
        Gradient magnitude of code ``0x7FFF``.
    depth : int
        Tree depth (the traversal stack needs ``depth + 1`` entries).
    n_nodes : int
        Nodes (without the chunk layout's padding slots).
    """

    nodes: np.ndarray
    layout: str
    chunk_depth: int
    frame_lo: np.ndarray
    frame_ext: np.ndarray
    root_box: np.ndarray
    grad_scale: float
    depth: int
    n_nodes: int
    build_ms: float = 0.0

    @property
    def words(self) -> np.ndarray:
        """The nodes as int64 (what the kernels read: signed shifts, no uint64 promotion)."""
        return self.nodes.view(np.int64)

    @property
    def frame_step(self) -> np.ndarray:
        """World/index distance of one plane code step per axis."""
        return self.frame_ext / float(pack.Q_ONE - pack.Q_ZERO)

    @property
    def nbytes(self) -> int:
        return int(self.nodes.nbytes)

    def record(self) -> BihRecord:
        """The arrays the traversal reads (:mod:`.traversal`)."""
        return BihRecord(self.words, self.preorder, np.ascontiguousarray(self.frame_lo, np.float64),
                         np.ascontiguousarray(self.frame_step, np.float64),
                         np.ascontiguousarray(self.root_box, np.float64), int(self.depth))

    @property
    def preorder(self) -> bool:
        return self.layout == "preorder"

    def decode(self) -> dict[str, np.ndarray]:
        """The tree back from the words, nodes numbered in depth-first pre-order.

        Returns arrays ``kind``, ``child`` (as :class:`BIHTree`), ``q`` (m, 2) plane
        codes in the :class:`BIHTree` convention (single child: ``(lo, hi)`` with
        0x0000 / 0xFFFF for an open side), ``density`` (14-bit codes), ``grad``
        (16-bit codes), ``first``, ``count`` (particle leaves). For tests and tools.
        """
        w = self.words
        m = self.n_nodes
        kind = np.zeros(m, np.int64)
        child = np.full((m, 2), -1, np.int64)
        q = np.zeros((m, 2), np.int64)
        dens = np.zeros(m, np.int64)
        grad = np.zeros((m, 3), np.int64)
        first = np.zeros(m, np.int64)
        count = np.zeros(m, np.int64)
        if m == 0:
            return dict(kind=kind, child=child, q=q, density=dens, grad=grad, first=first, count=count)
        stack = [(0, -1, 0)]  # (slot, parent id, which child)
        nid = 0
        while stack:
            slot, parent, which = stack.pop()
            i = nid
            nid += 1
            if parent >= 0:
                child[parent, which] = i
            word = int(w[slot])
            k = (word >> 62) & 3
            kind[i] = k
            if k == construct.LEAF:
                dens[i] = (word >> 48) & 0x3FFF
                for a in range(3):
                    grad[i, a] = (word >> (16 * a)) & 0xFFFF
                first[i] = (word >> 32) & 0x3FFFFFFF
                count[i] = word & 0xFFFFFFFF
                continue
            axis, c0, c1, single, q0, q1 = decode_inner(w, slot, self.preorder)
            if single:
                if q1 == pack.Q_POS_INF:
                    q[i] = (pack.Q_NEG_INF, q0)
                elif q0 == pack.Q_NEG_INF:
                    q[i] = (q1, pack.Q_POS_INF)
                else:
                    q[i] = (q0, q1)
                stack.append((int(c0), i, 0))
            else:
                q[i] = (q0, q1)
                stack.append((int(c1), i, 1))
                stack.append((int(c0), i, 0))
        return dict(kind=kind, child=child, q=q, density=dens, grad=grad, first=first, count=count)


def _check_depth(max_depth) -> int:
    if max_depth is None:
        return 1 << 30
    return as_int(max_depth, "max_depth", lo=0, expected="None or a non-negative integer")


def build_bih(elements: Elements, variant: str = "elaborate") -> BIHTree:
    """The intermediate BIH over ``elements`` with per-node statistics (module docstring).

    An empty element set gives a tree of 0 nodes (renderers draw the background).
    """
    one_of(variant, "variant", VARIANTS, expected=f"one of {VARIANTS}")
    t0 = time.perf_counter()
    n = len(elements)
    lo = np.array(elements.lo, np.float64, order="C", copy=True)
    hi = np.array(elements.hi, np.float64, order="C", copy=True)
    perm = np.arange(n, dtype=np.int64)
    cap = 2 * n + 64  # grown by the kernel when single-child nodes need more
    node_i = np.empty((cap, 6), np.int64)
    node_f = np.empty((cap, 2), np.float64)
    node_box = np.empty((cap, 6), np.float64)
    m, node_i, node_f, node_box = construct.build(lo, hi, VARIANTS.index(variant), node_i, node_f, node_box, perm)
    node_i = node_i[:m]
    kind = node_i[:, 0].astype(np.int8)
    child = np.ascontiguousarray(node_i[:, 1:3])
    first = np.ascontiguousarray(node_i[:, 3])
    count = np.ascontiguousarray(node_i[:, 4])
    depth = np.ascontiguousarray(node_i[:, 5])
    vol = np.empty(m)
    mean = np.empty(m)
    m2 = np.empty(m)
    grad = np.empty((m, 3))
    evol = np.prod(hi - lo, axis=1)
    if m:
        lod.node_stats(kind, child, first, count, evol, elements.density[perm], elements.gradient[perm],
                     vol, mean, m2, grad)
    var = m2 / np.maximum(count, 1)
    tree = BIHTree(kind, child, np.ascontiguousarray(node_f[:m]), np.ascontiguousarray(node_box[:m]), first,
                   count, depth, vol, mean, var, grad, perm, elements, variant)
    tree.build_ms = (time.perf_counter() - t0) * 1e3
    return tree


# Element BIHs depend on the volume, threshold, resampling and variant, not on the
# TF: a TF edit in an approximate mode reuses them (weakly keyed by the volume).
_ELEMENT_TREES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def element_tree(volume, threshold: float, resample: float, variant: str) -> BIHTree:
    """The (cached) intermediate BIH over ``volume``'s voxel elements."""
    per_vol = _ELEMENT_TREES.setdefault(volume, {})
    key = (float(threshold), float(resample), variant)
    tree = per_vol.get(key)
    if tree is None:
        t0 = time.perf_counter()
        el = voxel_elements(volume, threshold, resample)
        el_ms = (time.perf_counter() - t0) * 1e3
        tree = build_bih(el, variant)
        tree.elements.info["elements_ms"] = el_ms
        per_vol[key] = tree
    return tree


@register_index
class BIH(SpatialIndex):
    """Bounding interval hierarchy for DVR, in one of three modes.

    Parameters
    ----------
    volume, tf
        What to index.
    mode : {"ess", "single-sample", "multi-sample"}
        ``ess`` (default): a coarse BIH over the bricks that are non-empty for
        ``tf`` (full subtrees merged into one leaf); it only skips space, the
        renderer marches the global lattice inside its leaves: exact, the naive
        image. ``single-sample`` / ``multi-sample``: BIH-DVR over voxel elements
        (one approximated sample per leaf segment / the lattice samples inside each
        leaf, with density ``d_c + g . (x - c)``): approximate, ``exact`` is False.
    brick : int
        ``ess``: voxel cells per brick edge (default 8).
    threshold, resample : float
        Approximate modes: element threshold (normalised density, default 0.1) and
        resampling factor (1, 1.5 or 2).
    variant : {"elaborate", "basic"}
        Single-child planes (see the module docstring).
    max_depth, min_fill, max_std
        Approximate modes: LoD cut (defaults: unlimited, 0.75, 0.01).
    layout : {"preorder", "chunks"}, chunk_depth : int
        Packed node order.

    Notes
    -----
    An element set can be empty (no brick non-empty for the TF, no voxel at the
    threshold): the index then has 0 nodes and every ray sees the background.
    """

    name = "bih"
    exact = True  # for mode="ess"; instances in the approximate modes say False

    def __init__(self, volume, tf, mode: str = "ess", *, brick: int = 8, threshold: float = 0.1,
                 resample: float = 1.0, variant: str = "elaborate", max_depth: int | None = None,
                 min_fill: float = 0.75, max_std: float = 0.01, layout: str = "preorder",
                 chunk_depth: int = 2) -> None:
        super().__init__(volume, tf)
        one_of(mode, "mode", MODES, expected=f"one of {MODES}")
        one_of(variant, "variant", VARIANTS, expected=f"one of {VARIANTS}")
        self.mode = mode
        self.exact = mode == "ess"
        ph = self.build_phases
        clock = time.perf_counter
        t0 = clock()
        if mode == "ess":
            b = as_int(brick, "brick", 2, 64, expected="an integer in 2..64 (voxels per edge)")
            self.brick = b
            el = brick_elements(volume, tf, b)
            t1 = clock()
            ph["classify"] = (t1 - t0) * 1e3
            full = build_bih(el, variant)
            t2 = clock()
            ph["build"] = (t2 - t1) * 1e3
            # Merge subtrees whose bricks fill their box completely (same samples,
            # fewer leaves): the LoD cut at fill 1 with any density spread.
            self.tree = full.lod(None, 1.0, math.inf)
            t3 = clock()
            ph["merge"] = (t3 - t2) * 1e3
        else:
            hit = volume in _ELEMENT_TREES and (float(threshold), float(resample), variant) in _ELEMENT_TREES[volume]
            full = element_tree(volume, threshold, resample, variant)
            t2 = clock()
            if not hit:
                ph["elements"] = full.elements.info.get("elements_ms", 0.0)
                ph["build"] = full.build_ms
            self.full = full
            self.tree = full.lod(max_depth, min_fill, max_std)
            t3 = clock()
            ph["lod"] = (t3 - t2) * 1e3
        self.packed = self.tree.pack(layout, chunk_depth)
        ph["pack"] = (clock() - t3) * 1e3
        self.elements = full.elements
        self.nbytes = self.packed.nbytes
        v_lo, v_hi = (float(x) for x in volume.value_range)
        self.v_lo = v_lo
        self.v_span = v_hi - v_lo if v_hi > v_lo else 1.0

    def traversal_record(self, view: View) -> BihRecord | BihApproxRecord:
        p = self.packed
        tree = p.record()
        if self.mode == "ess":
            return tree
        mode = MODE_SINGLE if self.mode == "single-sample" else MODE_MULTI
        return BihApproxRecord(tree, mode, float(p.grad_scale), self.v_lo, self.v_span)

    def stats(self) -> dict:
        s = super().stats()
        s.update(mode=self.mode, elements=len(self.elements), nodes=self.tree.n_nodes,
                 leaves=self.tree.n_leaves, depth=self.tree.max_depth, layout=self.packed.layout)
        return s


@dataclass
class ParticleBIH:
    """A packed BIH over spheres, with the spheres in tree order.

    Leaves hold ``(first, count)`` into ``centers`` / ``radii`` / ``colors`` (the
    :class:`~sparsecast.elements.ParticleSet`'s arrays permuted to tree order).
    Built once per particle set; the radius scale is applied at render time.
    """

    particles: object
    tree: BIHTree
    packed: PackedBIH
    centers: np.ndarray
    radii: np.ndarray
    colors: np.ndarray

    @classmethod
    def build(cls, particles, variant: str = "elaborate", layout: str = "preorder",
              chunk_depth: int = 2) -> "ParticleBIH":
        tree = build_bih(particles.elements(), variant)
        packed = tree.pack(layout, chunk_depth)
        p = tree.perm
        return cls(particles, tree, packed, np.ascontiguousarray(particles.centers[p]),
                   np.ascontiguousarray(particles.radii[p]), np.ascontiguousarray(particles.colors[p]))

    @property
    def max_radius(self) -> float:
        return float(self.radii.max()) if self.radii.size else 0.0

    def stats(self) -> dict:
        s = self.tree.stats()
        s.update(bytes=self.packed.nbytes, pack_ms=self.packed.build_ms)
        return s
