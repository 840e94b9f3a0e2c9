"""Structure of the k-d trees and hybrid grids (issue 4); images are checked
against the naive marcher by test_ess_exactness.py."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.errors import ParameterError
from sparsecast.index.kdtree import occupancy
from sparsecast.index.kdtree import CellOccupancy
from sparsecast.index.kdtree.build import MIN_LEAF

from synthetic import sparse_volume

TREES = ["kdtree-shallow", "kdtree-deep", "hybrid-pc", "hybrid-mm"]


def _window_reduce(d: np.ndarray, offsets, op) -> np.ndarray:
    """Per cell, ``op`` over voxels ``c + o`` (o in offsets, clipped to the axis) on every axis."""
    for axis in range(3):
        n = d.shape[axis]
        c = np.arange(max(n - 1, 1))
        parts = [np.take(d, np.clip(c + o, 0, n - 1), axis=axis) for o in offsets]
        d = op.reduce(np.stack(parts), axis=0)
    return d


def brute_occupancy(vol: sc.Volume, tf: sc.TransferFunction) -> np.ndarray:
    """Cell c occupied iff the TF is non-zero somewhere in [min, max] of voxels c-1..c+2."""
    d = vol.data.astype(np.float64)
    lo = _window_reduce(d, (-1, 0, 1, 2), np.minimum)
    hi = _window_reduce(d, (-1, 0, 1, 2), np.maximum)
    return tf.classify(lo, hi).astype(np.uint8)


def corner_occupancy(vol: sc.Volume, tf: sc.TransferFunction) -> np.ndarray:
    """Cells whose own eight corners' range is non-empty (no apron)."""
    d = vol.data.astype(np.float64)
    lo = _window_reduce(d, (0, 1), np.minimum)
    hi = _window_reduce(d, (0, 1), np.maximum)
    return tf.classify(lo, hi)


def leaf_boxes(idx) -> np.ndarray:
    return idx.node_box[idx.node_axis < 0].astype(np.int64)


def check_tree(idx) -> None:
    occ = idx.cells.occ
    boxes = leaf_boxes(idx)
    # leaves are pairwise disjoint (half-open cell boxes)
    lo = np.maximum(boxes[:, None, :3], boxes[None, :, :3])
    hi = np.minimum(boxes[:, None, 3:], boxes[None, :, 3:])
    overlap = np.all(lo < hi, axis=2)
    np.fill_diagonal(overlap, False)
    assert not overlap.any(), f"leaves overlap: {np.argwhere(overlap)[:3]}"
    # leaves cover every occupied cell
    covered = np.zeros_like(occ, bool)
    for x0, y0, z0, x1, y1, z1 in boxes:
        covered[z0:z1, y0:y1, x0:x1] = True
    assert not np.any(occ.astype(bool) & ~covered)
    # every node is the tight box of its occupied cells; children inside the parent
    for n in range(idx.n_nodes):
        x0, y0, z0, x1, y1, z1 = idx.node_box[n]
        sub = occ[z0:z1, y0:y1, x0:x1]
        assert sub[0].any() and sub[-1].any() and sub[:, 0].any() and sub[:, -1].any()
        assert sub[:, :, 0].any() and sub[:, :, -1].any()
        a = idx.node_axis[n]
        if a >= 0:
            c = idx.node_child[n]
            s = idx.node_split[n]
            assert idx.node_box[c, a + 3] <= s <= idx.node_box[c + 1, a]
            for ch in (c, c + 1):
                assert np.all(idx.node_box[ch, :3] >= idx.node_box[n, :3])
                assert np.all(idx.node_box[ch, 3:] <= idx.node_box[n, 3:])


@pytest.fixture(scope="module")
def blobs():
    rng = np.random.default_rng(3)
    return sparse_volume(rng, (41, 50, 67), 12)


@pytest.mark.parametrize("name", TREES)
@pytest.mark.parametrize("threshold", [0.0, 0.1, 0.5])
def test_leaves_disjoint_and_cover(blobs, name, threshold):
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=threshold)
    idx = sc.build_index(blobs, tf, name)
    # The hybrids' grids keep the one-voxel apron; the k-d trees classify a cell by
    # its own corners and grow their boxes instead (kdtree/build.py, "Exactness").
    assert idx.apron == name.startswith("hybrid")
    if idx.apron:
        assert np.array_equal(idx.cells.occ, brute_occupancy(blobs, tf))
        # every cell with a non-empty corner range is occupied together with its neighbours
        core = corner_occupancy(blobs, tf)
        grown = np.pad(core, 1)
        dil = np.zeros_like(core)
        for dz in range(3):
            for dy in range(3):
                for dx in range(3):
                    dil |= grown[dz:dz + core.shape[0], dy:dy + core.shape[1], dx:dx + core.shape[2]]
        assert not np.any(dil & ~idx.cells.occ.astype(bool))
    else:
        assert np.array_equal(idx.cells.occ, corner_occupancy(blobs, tf).astype(np.uint8))
        assert idx.cells.n_occupied < brute_occupancy(blobs, tf).sum()  # the apron is not free
    check_tree(idx)


@pytest.mark.parametrize("name", ["kdtree-shallow", "kdtree-deep"])
def test_apron_option_classifies_with_the_apron(blobs, name):
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    idx = sc.build_index(blobs, tf, name, apron=True)
    assert idx.apron and np.array_equal(idx.cells.occ, brute_occupancy(blobs, tf))
    check_tree(idx)


def test_boxes_are_grown_by_the_margin(blobs):
    """Traversal boxes are the leaves' cell boxes grown by BOX_MARGIN on every side."""
    from sparsecast.index.kdtree.build import BOX_MARGIN

    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    idx = sc.build_index(blobs, tf, "kdtree-deep")
    top = np.array(blobs.shape[::-1], np.float64) - 1
    cells = leaf_boxes(idx).astype(np.float64)
    assert np.array_equal(idx.leaf_lo, np.minimum(cells[:, :3], top) - BOX_MARGIN)
    assert np.array_equal(idx.leaf_hi, np.minimum(cells[:, 3:], top) + BOX_MARGIN)


def test_non_monotonic_tf_classification():
    """Two transparent corner values can blend to an opaque one: the cell is occupied."""
    data = np.zeros((4, 4, 4), np.float32)
    data[1, 1, 1] = 1.0  # values 0 and 1 transparent, 0.5 opaque
    tf = sc.TransferFunction([(0, 1, 1, 1, 0), (0.4, 1, 1, 1, 0), (0.5, 1, 1, 1, 1), (0.6, 1, 1, 1, 0),
                              (1, 1, 1, 1, 0)])
    vol = sc.Volume(data)
    idx = sc.build_index(vol, tf, "kdtree-deep")
    assert idx.cells.occ[1, 1, 1] and idx.cells.occ[0, 0, 0]
    check_tree(idx)


@settings(max_examples=40, deadline=None)
@given(shape=st.tuples(*(st.integers(1, 75) for _ in range(3))), seed=st.integers(0, 2**31),
       density=st.sampled_from([0.0, 0.001, 0.02, 0.3, 1.0]))
def test_svt_tight_box_equals_brute_force(shape, seed, density):
    rng = np.random.default_rng(seed)
    occ = (rng.random(shape) < density).astype(np.uint8)
    cells = CellOccupancy.from_occupancy(occ)
    assert cells.n_occupied == int(occ.sum())
    for _ in range(25):
        lo = [int(rng.integers(0, n)) for n in shape]
        hi = [int(rng.integers(l + 1, n + 1)) for l, n in zip(lo, shape)]
        box = [lo[2], lo[1], lo[0], hi[2], hi[1], hi[0]]
        sub = occ[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
        assert cells.count(box) == int(sub.sum())
        got = cells.tight(box)
        if not sub.any():
            assert got is None
            continue
        z, y, x = np.nonzero(sub)
        want = [x.min() + lo[2], y.min() + lo[1], z.min() + lo[0],
                x.max() + 1 + lo[2], y.max() + 1 + lo[1], z.max() + 1 + lo[0]]
        assert list(got) == want


def test_hybrid_grid_from_svts(blobs):
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    idx = sc.build_index(blobs, tf, "hybrid-pc")
    occ = idx.cells.occ
    want = np.zeros(idx.occupied.shape, np.uint8)
    for gz, gy, gx in np.ndindex(*want.shape):
        want[gz, gy, gx] = occ[16 * gz:16 * gz + 16, 16 * gy:16 * gy + 16, 16 * gx:16 * gx + 16].any()
    assert np.array_equal(idx.occupied, want)
    # and it is at least as conservative as the grid's own classification
    grid = sc.build_index(blobs, tf, "grid-pc", cell=16)
    assert np.all(idx.occupied <= grid.occupied)


@pytest.mark.parametrize("threshold", [0.0, 0.1, 0.4])
def test_shallow_halting_rule(blobs, threshold):
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=threshold)
    idx = sc.build_index(blobs, tf, "kdtree-shallow")
    vol = np.prod(idx.node_box[:, 3:] - idx.node_box[:, :3], axis=1)
    if idx.n_nodes > 1:
        assert np.all(vol >= 0.1 * vol[0])
    for n in np.flatnonzero(idx.node_axis >= 0):
        c = idx.node_child[n]
        assert vol[c] + vol[c + 1] < vol[n]
    assert idx.n_leaves <= 10


@pytest.mark.parametrize("min_leaf", [None, 8])
def test_deep_min_leaf(blobs, min_leaf):
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    idx = sc.build_index(blobs, tf, "kdtree-deep", **({} if min_leaf is None else {"min_leaf": min_leaf}))
    assert idx.min_leaf == (MIN_LEAF if min_leaf is None else min_leaf) and idx.n_leaves > 1
    for n in range(idx.n_nodes):
        a = idx.node_axis[n]
        box = idx.node_box[n]
        m = idx.min_leaf
        if a >= 0:  # the plane leaves >= min_leaf cells of the parent on both sides
            s = idx.node_split[n]
            assert s - box[a] >= m and box[a + 3] - s >= m
        else:  # a leaf is too small to split, or at least half occupied (full or no plane helped)
            ext = box[3:] - box[:3]
            assert np.all(ext < 2 * m) or 2 * idx.cells.count(box) >= np.prod(ext)


@pytest.mark.parametrize("name", TREES)
def test_empty_classification(blobs, name):
    tf = sc.TransferFunction([(0, 1, 1, 1, 0), (1, 1, 1, 1, 0)])
    idx = sc.build_index(blobs, tf, name)
    assert idx.n_nodes == 0 and idx.n_leaves == 0
    img = sc.render(blobs, tf, sc.Camera.orbit(blobs), 8, 8, index=idx)
    assert img.stats["samples"] == 0
    zeros = sc.Volume(np.zeros((9, 10, 11), np.uint8))
    tf2 = sc.TransferFunction.preset("magma", (0, 255), threshold=0.2)
    assert sc.build_index(zeros, tf2, name).n_nodes == 0


@pytest.mark.parametrize("name", TREES)
def test_all_full(blobs, name):
    tf = sc.TransferFunction([(0, 0.2, 0.4, 0.9, 0.05), (1, 1, 1, 1, 0.3)])
    idx = sc.build_index(blobs, tf, name)
    assert idx.n_nodes == 1 and idx.n_leaves == 1
    nz, ny, nx = blobs.shape
    assert list(idx.node_box[0]) == [0, 0, 0, nx - 1, ny - 1, nz - 1]
    from sparsecast.index.kdtree.build import BOX_MARGIN

    assert np.array_equal(idx.leaf_hi[0], np.array([nx - 1, ny - 1, nz - 1], np.float64) + BOX_MARGIN)
    assert np.array_equal(idx.leaf_lo[0], np.zeros(3) - BOX_MARGIN)


@pytest.mark.parametrize("shape", [(1, 1, 1), (1, 5, 7), (3, 1, 40), (2, 2, 2)])
def test_degenerate_shapes(shape):
    rng = np.random.default_rng(1)
    vol = sc.Volume(rng.random(shape).astype(np.float32))
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.5)
    for name in TREES:
        idx = sc.build_index(vol, tf, name)
        check_tree(idx)


@pytest.mark.parametrize("bins", [0, 4, 16])
def test_binning_gives_valid_trees(blobs, bins):
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    for name in ("kdtree-shallow", "kdtree-deep"):
        idx = sc.build_index(blobs, tf, name, bins=bins, bin_levels=2)
        check_tree(idx)
        s = idx.stats()
        for key in ("height", "nodes", "leaves", "bytes", "phases", "svt_bytes"):
            assert key in s
        assert {"classify", "svt", "split"} <= set(s["phases"])


def test_leaf_order_front_to_back(blobs):
    """For every eye, a leaf never comes after a leaf that hides part of it."""
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    idx = sc.build_index(blobs, tf, "kdtree-deep", min_leaf=4)
    rng = np.random.default_rng(0)
    lo, hi = idx.leaf_lo, idx.leaf_hi
    for _ in range(20):
        eye = rng.uniform(-20, 90, 3)
        order = idx.leaf_order(eye, True)
        assert sorted(order) == list(range(idx.n_leaves))
        rank = np.empty_like(order)
        rank[order] = np.arange(order.size)
        # rays from the eye through random points of leaf j: any leaf i hit
        # strictly earlier along the ray must come before j
        for _ in range(30):
            j = int(rng.integers(idx.n_leaves))
            p = rng.uniform(lo[j], hi[j])
            d = p - eye
            for i in range(idx.n_leaves):
                if i == j:
                    continue
                inv = np.where(d != 0, 1.0 / np.where(d != 0, d, 1), np.inf)
                t0 = np.minimum((lo[i] - eye) * inv, (hi[i] - eye) * inv)
                t1 = np.maximum((lo[i] - eye) * inv, (hi[i] - eye) * inv)
                tn, tf_ = max(t0.max(), 0.0), min(t1.min(), 1.0)
                if tn < tf_ - 1e-9:  # leaf i lies between the eye and p
                    assert rank[i] < rank[j]


def test_bad_options(blobs):
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    with pytest.raises(ParameterError):
        sc.build_index(blobs, tf, "kdtree-shallow", bins=-1)
    with pytest.raises(ParameterError):
        sc.build_index(blobs, tf, "kdtree-deep", min_leaf=0)
    with pytest.raises(ParameterError):
        sc.build_index(blobs, tf, "kdtree-shallow", min_frac=1.5)
    with pytest.raises(ParameterError):
        sc.build_index(blobs, tf, "kdtree-shallow", nope=1)
    assert occupancy.SVT_BRICK % 16 == 0
