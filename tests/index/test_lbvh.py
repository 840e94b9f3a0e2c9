"""LBVH over bricks: structure of the tree, build phases, voting paths, Morton codes.

Image exactness (== naive) is checked for every registered index, LBVH options
included, by tests/test_ess_exactness.py; here: what the tree looks like.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from synthetic import sparse_volume
from sparsecast.errors import ParameterError
from sparsecast.index.lbvh import construct as K
from sparsecast.kernels.classify import _classify_parallel, _classify_serial
from sparsecast.index.lbvh import LBVH, brick_grid_shape, vote_bricks, vote_voxels

PHASES = ["voting", "compaction", "morton", "sort", "hierarchy", "refit", "layout"]


def blobs(shape, n_blobs, seed=0) -> sc.Volume:
    return sparse_volume(np.random.default_rng(seed), shape, n_blobs)


VIRIDIS = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.15)
DENSE = sc.TransferFunction([(0, 0.2, 0.4, 0.9, 0.05), (1, 1, 1, 1, 0.3)])
CLEAR = sc.TransferFunction([(0, 1, 1, 1, 0), (1, 1, 1, 1, 0)])


def brick_box(vol, brick, flat_id):
    """Index-space box of a brick, by the contract ``[b*B, min((b+1)*B, n-1)]``."""
    nbz, nby, nbx = brick_grid_shape(vol.shape, brick)
    bz, r = divmod(int(flat_id), nby * nbx)
    by, bx = divmod(r, nbx)
    nz, ny, nx = vol.shape
    lo = np.array([bx, by, bz]) * brick
    hi = np.minimum((np.array([bx, by, bz]) + 1) * brick, np.array([nx, ny, nz]) - 1)
    return lo, hi


def check_structure(idx: LBVH):
    """Every non-empty brick in exactly one leaf; boxes nest; 2L-1 nodes; pre-order."""
    vol, B = idx.volume, idx.brick
    occ = vote_bricks(vol, idx.tf, B)
    expected = np.flatnonzero(occ)
    assert np.array_equal(np.sort(idx.bricks), expected)
    m = idx.n_nodes
    if expected.size == 0:
        assert m == 0 and idx.n_leaves == 0
        return
    leaves = np.flatnonzero(idx.child[:, 0] < 0)
    inner = np.flatnonzero(idx.child[:, 0] >= 0)
    assert m == 2 * leaves.size - 1 and inner.size == leaves.size - 1
    assert np.all((idx.child[leaves] == -1))
    # Each node except the root is the child of exactly one node.
    kids = idx.child[inner].ravel()
    assert np.array_equal(np.sort(kids), np.arange(1, m))
    assert np.all(kids > np.repeat(inner, 2))  # pre-order: children after their parent
    # Leaves partition the Morton-sorted brick list.
    cover = np.zeros(idx.n_bricks, np.int64)
    for leaf in leaves:
        cover[idx.leaf_first[leaf]: idx.leaf_first[leaf] + idx.leaf_count[leaf]] += 1
    assert np.all(cover == 1)
    # Every node's box contains its children's; leaves' boxes are exactly the union of their bricks'.
    for i in inner:
        for c in idx.child[i]:
            assert np.all(idx.box[i, :3] <= idx.box[c, :3]) and np.all(idx.box[c, 3:] <= idx.box[i, 3:])
        a, b = idx.child[i]
        assert idx.leaf_count[i] == idx.leaf_count[a] + idx.leaf_count[b]
    for leaf in leaves:
        f, n = idx.leaf_first[leaf], idx.leaf_count[leaf]
        boxes = np.array([np.concatenate(brick_box(vol, B, b)) for b in idx.bricks[f:f + n]])
        union = np.concatenate([boxes[:, :3].min(0), boxes[:, 3:].max(0)])
        if idx.prune is None:
            assert n == 1
        assert np.array_equal(idx.box[leaf], union)
    # Sorted codes, and depth within bounds.
    assert np.all(np.diff(idx.codes) >= 0)
    assert 0 <= idx.depth <= m


@pytest.mark.parametrize("brick", [4, 8, 16])
@pytest.mark.parametrize("prune", [None, 0.25, 1.0])
def test_structure_sparse(brick, prune):
    vol = blobs((37, 29, 45), 9, seed=3)
    idx = sc.build_index(vol, VIRIDIS, "lbvh", brick=brick, prune=prune)
    check_structure(idx)
    assert list(idx.build_phases) == PHASES
    s = idx.stats()
    for key in ("leaves", "inner_nodes", "depth", "bytes", "phases", "bricks"):
        assert key in s
    assert s["leaves"] == idx.n_leaves and s["inner_nodes"] == idx.n_nodes - idx.n_leaves


def test_one_nonempty_brick():
    data = np.zeros((30, 30, 30), np.float32)
    data[12, 13, 11] = 1.0  # within bricks 1 (and its apron neighbours) on each axis
    vol = sc.Volume(data)
    tf = sc.TransferFunction([(0.0, 1, 1, 1, 0), (0.4, 1, 1, 1, 0), (1, 1, 1, 1, 1)])
    occ = vote_bricks(vol, tf, 16)
    assert occ.sum() == 1
    idx = sc.build_index(vol, tf, "lbvh", brick=16)
    check_structure(idx)
    assert idx.n_nodes == 1 and idx.depth == 0
    assert np.array_equal(idx.box[0], [0, 0, 0, 16, 16, 16])


def test_all_empty_and_all_nonempty():
    vol = blobs((20, 21, 22), 3, seed=1)
    empty = sc.build_index(vol, CLEAR, "lbvh")
    check_structure(empty)
    assert empty.n_nodes == 0 and empty.stats()["leaves"] == 0
    full = sc.build_index(vol, DENSE, "lbvh", brick=4)
    check_structure(full)
    assert full.n_bricks == np.prod(brick_grid_shape(vol.shape, 4))
    # Pruning a full grid collapses it into one leaf: the whole domain.
    one = sc.build_index(vol, DENSE, "lbvh", brick=4, prune=1.0)
    check_structure(one)
    assert one.n_nodes == 1
    assert np.array_equal(one.box[0], [0, 0, 0, 21, 20, 19])


@pytest.mark.parametrize("shape", [(1, 1, 1), (1, 5, 9), (2, 2, 2), (9, 1, 17)])
def test_degenerate_shapes(shape):
    vol = sc.Volume(np.random.default_rng(0).uniform(size=shape).astype(np.float32))
    idx = sc.build_index(vol, DENSE, "lbvh", brick=4)
    check_structure(idx)
    if min(shape) < 2:  # built, but render() refuses one-voxel-thick volumes (issue 14, item 12)
        with pytest.raises(sc.errors.VolumeDataError, match="at least 2 voxels"):
            sc.render(vol, DENSE, sc.Camera.orbit(vol, 20, 30), 9, 7, index=idx)
        return
    cam = sc.Camera.orbit(vol, 20, 30)
    ref = sc.render(vol, DENSE, cam, 9, 7)
    img = sc.render(vol, DENSE, cam, 9, 7, index=idx)
    assert np.abs(img.rgba - ref.rgba).max() <= 1e-5


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), shape=st.tuples(*[st.integers(2, 40)] * 3),
       brick=st.sampled_from([2, 4, 8, 16]), threshold=st.sampled_from([0.0, 0.1, 0.3, 0.7]),
       prune=st.sampled_from([None, 0.1, 0.5, 0.9]))
def test_property_structure_and_voting(seed, shape, brick, threshold, prune):
    vol = blobs(shape, 4, seed=seed % 1000)
    tf = sc.TransferFunction.preset("magma", (0.0, 1.0), threshold=threshold)
    # The per-voxel pass classifies every brick exactly as the cached min/max does.
    assert np.array_equal(vote_voxels(vol, tf, brick), vote_bricks(vol, tf, brick))
    stats = vol.brick_stats(brick)
    assert np.array_equal(vote_bricks(vol, tf, brick), tf.classify(stats.vmin, stats.vmax).ravel())
    a = LBVH(vol, tf, brick=brick, prune=prune, voting="voxels")
    b = LBVH(vol, tf, brick=brick, prune=prune, voting="bricks")
    check_structure(a)
    for name in ("child", "box", "bricks", "leaf_first", "leaf_count"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_voting_voxels_ignores_the_cache():
    vol = blobs((24, 24, 24), 4, seed=2)
    idx = LBVH(vol, VIRIDIS, voting="voxels")
    assert idx.stats()["voting"] == "voxels"
    assert 8 not in vol._bricks  # the per-voxel path did its own pass


# -- Morton codes ------------------------------------------------------------------
def morton_ref(x, y, z, bits):
    code = 0
    for i in range(bits):
        code |= ((x >> i) & 1) << (3 * i) | ((y >> i) & 1) << (3 * i + 1) | ((z >> i) & 1) << (3 * i + 2)
    return code


@settings(max_examples=200, deadline=None)
@given(x=st.integers(0, 2**21 - 1), y=st.integers(0, 2**21 - 1), z=st.integers(0, 2**21 - 1))
def test_morton63_matches_bitwise_reference(x, y, z):
    assert K.morton63(x, y, z) == morton_ref(x, y, z, 21)
    assert K.morton30(x & 1023, y & 1023, z & 1023) == morton_ref(x & 1023, y & 1023, z & 1023, 10)


def test_morton_extremes_and_order():
    top = 2**21 - 1
    assert K.morton63(top, top, top) == 2**63 - 1
    assert K.morton30(1023, 1023, 1023) == 2**30 - 1
    # Beyond 1024 bricks per axis the 30-bit code would alias; the 63-bit one does not.
    assert K.morton30(1024, 0, 0) == K.morton30(0, 0, 0)
    assert K.morton63(1024, 0, 0) != K.morton63(0, 0, 0)
    ids = np.array([0, 1, 2047, 2048, 2048 * 3000 + 5], np.int64)
    c30 = K.morton_codes(ids, 4000, 2048, False)
    c63 = K.morton_codes(ids, 4000, 2048, True)
    coords = [(i % 2048, (i // 2048) % 4000, i // (2048 * 4000)) for i in ids]
    assert list(c63) == [morton_ref(*c, 21) for c in coords]
    assert list(c30) == [morton_ref(*(v & 1023 for v in c), 10) for c in coords]


# -- sort and hierarchy on raw keys (duplicates included) --------------------------
def test_radix_argsort_is_stable_and_equals_numpy():
    rng = np.random.default_rng(4)
    for top in (1, 2**10, 2**30, 2**62):
        keys = rng.integers(0, top, size=5000, dtype=np.int64)
        assert np.array_equal(K.radix_argsort(keys), np.argsort(keys, kind="stable"))
    assert K.radix_argsort(np.zeros(0, np.int64)).size == 0


def build_raw(codes):
    n = codes.size
    m = 2 * n - 1
    left, right, parent, first, last = (np.full(m, -7, np.int64) for _ in range(5))
    K.karras_hierarchy(codes, left, right, parent, first, last)
    return left, right, parent, first, last


@settings(max_examples=60, deadline=None)
@given(codes=st.lists(st.integers(0, 40), min_size=1, max_size=200))
def test_karras_tree_with_duplicate_codes(codes):
    """Sorted keys with (possibly many) duplicates still give a binary tree whose
    nodes cover contiguous leaf ranges, split exactly between their children."""
    codes = np.sort(np.array(codes, np.int64))
    n = codes.size
    left, right, parent, first, last = build_raw(codes)
    m = 2 * n - 1
    assert parent[0] == -1
    inner = np.arange(n - 1)
    kids = np.concatenate([left[inner], right[inner]])
    assert np.array_equal(np.sort(kids), np.arange(1, m))
    for i in inner:
        lc, rc = left[i], right[i]
        assert parent[lc] == i and parent[rc] == i
        assert first[lc] == first[i] and last[rc] == last[i] and last[lc] + 1 == first[rc]
    assert first[0] == 0 and last[0] == n - 1
    for k in range(n):
        assert left[n - 1 + k] == -1 and first[n - 1 + k] == k == last[n - 1 + k]


def test_bad_options():
    vol = blobs((10, 10, 10), 1)
    for kw in ({"brick": 1}, {"brick": 3.5}, {"brick": "x"}, {"prune": 0.0}, {"prune": 1.5},
               {"prune": "a"}, {"voting": "cells"}):
        with pytest.raises(ParameterError):
            sc.build_index(vol, VIRIDIS, "lbvh", **kw)


def test_parallel_and_serial_build_kernels_agree():
    """Large inputs take the parallel paths; they must equal the serial ones."""
    rng = np.random.default_rng(7)
    n = K.PARALLEL_MIN + 123
    codes = np.sort(rng.integers(0, n // 3, size=n).astype(np.int64))  # many duplicates
    par = [np.full(2 * n - 1, -7, np.int64) for _ in range(5)]
    ser = [np.full(2 * n - 1, -7, np.int64) for _ in range(5)]
    K.karras_hierarchy(codes, *par)  # n >= PARALLEL_MIN: parallel
    for i in range(n - 1):
        K._karras_node(codes, n, i, *ser)
    ser[2][0] = -1  # the root's parent, set by the driver
    for a, b in zip(par, ser):
        assert np.array_equal(a[: n - 1], b[: n - 1])
    assert np.array_equal(par[2], ser[2])  # parents of leaves too
    lo = rng.uniform(0, 1, 5000)
    hi = lo + rng.uniform(0, 0.2, lo.size)
    tf = sc.TransferFunction.preset("magma", (0.0, 1.0), threshold=0.5)
    out_serial = np.empty(lo.size, np.bool_)
    out_parallel = np.empty(lo.size, np.bool_)
    _classify_serial(tf.prefix, 0.0, tf.scale, lo, hi, out_serial)
    _classify_parallel(tf.prefix, 0.0, tf.scale, lo, hi, out_parallel)
    assert np.array_equal(out_serial, out_parallel)
    assert np.array_equal(K.classify_bricks(tf.prefix, 0.0, tf.scale, lo, hi), out_serial)
    ids = np.sort(rng.choice(64**3, size=n, replace=False)).astype(np.int64)
    codes = K.morton_codes(ids, 64, 64, False)
    ref = [morton_ref(int(i % 64), int(i // 64 % 64), int(i // 4096), 10) for i in ids[:500]]
    assert list(codes[:500]) == ref


def test_many_leaves_per_ray():
    """Two-voxel bricks, every one non-empty: long runs of leaves per ray (merged
    into one segment), pruned and not; the same image and samples as naive."""
    vol = blobs((30, 26, 33), 12, seed=5)
    cam = sc.Camera.orbit(vol, 35, 25)
    ref = sc.render(vol, DENSE, cam, 16, 14, ert=1.0)
    for opts in ({"brick": 2}, {"brick": 4, "prune": 0.3}, {"brick": 2, "prune": 1.0}):
        img = sc.render(vol, DENSE, cam, 16, 14, index="lbvh", ert=1.0, **opts)
        assert np.abs(img.rgba - ref.rgba).max() <= 1e-5
        assert img.stats["samples"] == ref.stats["samples"]


def test_wide_morton_codes_on_a_long_thin_volume():
    """More than 1024 bricks along x (brick=2, 2101 voxels): 63-bit codes, still exact."""
    x = np.arange(2101, dtype=np.float64)
    row = (0.5 + 0.5 * np.sin(x / 37.0)) * (np.sin(x / 5.0) > 0.3)
    data = np.broadcast_to(row, (3, 2, 2101)).astype(np.float32).copy()
    vol = sc.Volume(data)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.4)
    idx = sc.build_index(vol, tf, "lbvh", brick=2)
    assert idx.wide_codes and idx.stats()["morton_bits"] == 63
    check_structure(idx)
    cam = sc.Camera.look_at((1050, 0.5, 40), (1050, 0.5, 0), up=(0, 1, 0), projection="orthographic",
                            ortho_height=2)  # 128 voxels along x, two of four rows inside
    ref = sc.render(vol, tf, cam, 256, 4, ert=1.0)
    img = sc.render(vol, tf, cam, 256, 4, index=idx, ert=1.0)
    assert np.abs(img.rgba - ref.rgba).max() <= 1e-5
    assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"] > 0
