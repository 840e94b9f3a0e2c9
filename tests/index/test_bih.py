"""BIH over elements: structural invariants, statistics, LoD, packed nodes, modes.

Exactness of ``mode="ess"`` against naive is covered by test_ess_exactness.py
(``INDEX_OPTIONS["bih"]``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.elements import Elements, voxel_elements
from sparsecast.errors import ParameterError
from sparsecast.index.bih import construct, pack
from sparsecast.index.bih import BIH, build_bih
from synthetic import sparse_volume

VARIANTS = ["elaborate", "basic"]


def make_elements(lo, hi, density=None, gradient=None):
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    n = lo.shape[0]
    flo = lo.min(0) if n else np.zeros(3)
    fhi = hi.max(0) if n else np.ones(3)
    dens = np.linspace(0.1, 0.9, n) if density is None else np.asarray(density, np.float64)
    grad = np.zeros((n, 3)) if gradient is None else np.asarray(gradient, np.float64)
    return Elements(lo, hi, dens, grad, flo, np.maximum(fhi - flo, 1e-9), "voxels")


def grid_cells(rng, n, dims=(12, 9, 7), size=1.0):
    """``n`` distinct cells of a grid, as non-overlapping cuboids."""
    total = int(np.prod(dims))
    ids = rng.choice(total, size=min(n, total), replace=False)
    z, rem = np.divmod(ids, dims[0] * dims[1])
    y, x = np.divmod(rem, dims[0])
    lo = np.stack([x, y, z], 1).astype(np.float64) * size
    return make_elements(lo, lo + size, rng.uniform(0, 1, len(ids)), rng.normal(0, 0.1, (len(ids), 3)))


def check_structure(tree):
    """Every element in exactly one leaf; boxes and planes bound their elements;
    intermediate leaves are exactly their (identical) elements' AABB."""
    el = tree.elements
    n = len(el)
    lo = el.lo[tree.perm]
    hi = el.hi[tree.perm]
    leaves = np.flatnonzero(tree.kind == construct.LEAF)
    seen = np.zeros(n, np.int64)
    for i in leaves:
        seen[tree.first[i]:tree.first[i] + tree.count[i]] += 1
    assert np.all(seen == 1)
    assert sorted(tree.perm.tolist()) == list(range(n))
    for i in range(tree.n_nodes):
        b, e = tree.first[i], tree.first[i] + tree.count[i]
        assert e > b
        assert np.all(lo[b:e] >= tree.box[i, :3]) and np.all(hi[b:e] <= tree.box[i, 3:])
        if tree.kind[i] == construct.LEAF:
            continue
        a = tree.kind[i]
        c0, c1 = tree.child[i]
        p0, p1 = tree.plane[i]
        if c1 >= 0:
            lb, le = tree.first[c0], tree.first[c0] + tree.count[c0]
            rb, re = tree.first[c1], tree.first[c1] + tree.count[c1]
            assert (lb, re) == (b, e) and le == rb
            assert np.all(hi[lb:le, a] <= p0) and np.isclose(hi[lb:le, a].max(), p0)
            assert np.all(lo[rb:re, a] >= p1) and np.isclose(lo[rb:re, a].min(), p1)
            assert c0 == i + 1  # pre-order
        else:
            assert (tree.first[c0], tree.count[c0]) == (b, e - b)
            assert p0 <= p1 and not (p0 == -math.inf and p1 == math.inf)
            assert np.all(lo[b:e, a] >= p0) and np.all(hi[b:e, a] <= p1)
            if tree.variant == "basic":
                assert math.isinf(p0) or math.isinf(p1)
    for i in leaves:
        b, e = tree.first[i], tree.first[i] + tree.count[i]
        assert np.array_equal(tree.box[i], np.concatenate([lo[b:e].min(0), hi[b:e].max(0)]))
        assert np.all(lo[b:e] == lo[b]) and np.all(hi[b:e] == hi[b])


@pytest.mark.parametrize("variant", VARIANTS)
def test_structure_voxel_elements(variant):
    rng = np.random.default_rng(3)
    vol = sparse_volume(rng, (18, 21, 25), 5)
    for r in (1.0, 1.5, 2.0):
        el = voxel_elements(vol, 0.1, r)
        assert len(el) > 50
        tree = build_bih(el, variant)
        check_structure(tree)
        assert tree.n_leaves == len(el)  # distinct voxels: one per leaf


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 60), variant=st.sampled_from(VARIANTS),
       dup=st.booleans())
def test_structure_random_boxes(seed, n, variant, dup):
    """Overlapping boxes of any size, possibly duplicated."""
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-5, 5, (n, 3)).round(1)
    hi = lo + rng.uniform(0, 3, (n, 3)).round(1)
    if dup:
        lo = np.concatenate([lo, lo[: n // 2 + 1]])
        hi = np.concatenate([hi, hi[: n // 2 + 1]])
    check_structure(build_bih(make_elements(lo, hi), variant))


def test_statistics_bottom_up():
    rng = np.random.default_rng(1)
    el = grid_cells(rng, 300)
    tree = build_bih(el)
    d = el.density[tree.perm]
    g = el.gradient[tree.perm]
    v = el.volume[tree.perm]
    for i in range(tree.n_nodes):
        b, e = tree.first[i], tree.first[i] + tree.count[i]
        assert tree.elem_volume[i] == pytest.approx(v[b:e].sum())
        assert tree.mean[i] == pytest.approx(d[b:e].mean())
        assert tree.var[i] == pytest.approx(d[b:e].var(), abs=1e-12)
        assert np.allclose(tree.grad[i], g[b:e].mean(0))


def test_lod_cut():
    rng = np.random.default_rng(2)
    el = grid_cells(rng, 400)
    tree = build_bih(el)
    # Everything collapses into the root when any fill and spread are allowed.
    root = tree.lod(None, 0.0, math.inf)
    assert root.n_nodes == 1 and root.kind[0] == construct.LEAF and root.mean[0] == pytest.approx(el.density.mean())
    # No criterion met: the cut is the whole tree.
    same = tree.lod(None, 1.0, 0.0)
    assert same.n_nodes == tree.n_nodes and np.array_equal(same.child, tree.child)
    for md in (0, 1, 3):
        cut = tree.lod(md)
        assert cut.max_depth <= md
        leaves = np.flatnonzero(cut.kind == construct.LEAF)
        seen = np.zeros(len(el), np.int64)
        for i in leaves:
            seen[cut.first[i]:cut.first[i] + cut.count[i]] += 1
        assert np.all(seen == 1)
    # Uniform density in a full box: one LoD leaf over a dense block.
    lo = np.stack(np.meshgrid(np.arange(4), np.arange(4), np.arange(4), indexing="ij"), -1).reshape(-1, 3)
    block = build_bih(make_elements(lo, lo + 1.0, np.full(64, 0.5)))
    assert block.lod().n_nodes == 1
    with pytest.raises(ParameterError, match="min_fill"):
        tree.lod(None, 1.5)
    with pytest.raises(ParameterError, match="max_depth"):
        tree.lod(-1)


def walk_packed(packed, dec):
    """Boxes of the decoded tree from the root box and the dequantized planes."""
    m = dec["kind"].shape[0]
    boxes = np.zeros((m, 6))
    if m == 0:
        return boxes
    boxes[0] = packed.root_box
    step = packed.frame_step
    for i in range(m):
        k = dec["kind"][i]
        if k == construct.LEAF:
            continue
        q0, q1 = dec["q"][i]
        p0 = pack.dequantize_plane(q0, packed.frame_lo[k], step[k])
        p1 = pack.dequantize_plane(q1, packed.frame_lo[k], step[k])
        c0, c1 = dec["child"][i]
        if c1 >= 0:
            boxes[c0] = boxes[i]
            boxes[c0, 3 + k] = min(boxes[i, 3 + k], p0)
            boxes[c1] = boxes[i]
            boxes[c1, k] = max(boxes[i, k], p1)
        else:
            boxes[c0] = boxes[i]
            boxes[c0, k] = max(boxes[i, k], p0)
            boxes[c0, 3 + k] = min(boxes[i, 3 + k], p1)
    return boxes


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("layout, chunk_depth", [("preorder", 2), ("chunks", 1), ("chunks", 2), ("chunks", 3)])
def test_pack_decode_round_trip(variant, layout, chunk_depth):
    rng = np.random.default_rng(4)
    vol = sparse_volume(rng, (16, 20, 23), 4)
    el = voxel_elements(vol, 0.1, 1.5)
    for tree in (build_bih(el, variant), build_bih(el, variant).lod()):
        packed = tree.pack(layout, chunk_depth)
        dec = packed.decode()
        assert packed.n_nodes == tree.n_nodes and packed.nbytes == 8 * packed.nodes.shape[0]
        assert np.array_equal(dec["kind"], tree.kind)
        assert np.array_equal(dec["child"], tree.child)
        step = packed.frame_step
        leaves = tree.kind == construct.LEAF
        assert np.array_equal(dec["density"][leaves], np.rint(tree.mean[leaves] * pack.DENSITY_MAX))
        g = (dec["grad"][leaves] - pack.GRAD_ZERO) / pack.GRAD_MAX * packed.grad_scale
        assert np.all(np.abs(g - tree.grad[leaves]) <= 0.5 * packed.grad_scale / pack.GRAD_MAX + 1e-12)
        # Fixed-point planes: within one step, rounded outward.
        for i in np.flatnonzero(~leaves):
            a = tree.kind[i]
            for s in range(2):
                x = tree.plane[i, s]
                back = pack.dequantize_plane(dec["q"][i, s], packed.frame_lo[a], step[a])
                if math.isinf(x):
                    assert back == x
                    continue
                upper = (s == 0) if tree.child[i, 1] >= 0 else (s == 1)
                err = back - x if upper else x - back
                assert -1e-9 * step[a] <= err <= step[a] * (1 + 1e-9)
        # The decoded tree's boxes still bound their elements.
        boxes = walk_packed(packed, dec)
        lo = el.lo[tree.perm]
        hi = el.hi[tree.perm]
        for i in range(tree.n_nodes):
            b, e = tree.first[i], tree.first[i] + tree.count[i]
            assert np.all(lo[b:e] >= boxes[i, :3] - 1e-9) and np.all(hi[b:e] <= boxes[i, 3:] + 1e-9)
            assert np.all(np.abs(boxes[i] - tree.box[i]) <= step[[0, 1, 2, 0, 1, 2]] * (1 + 1e-9))


def test_fixed_point_codes():
    lo, ext = 2.0, 10.0
    assert pack.quantize_plane(2.0, lo, ext, False) == pack.Q_ZERO
    assert pack.quantize_plane(12.0, lo, ext, True) == pack.Q_ONE
    assert pack.quantize_plane(math.inf, lo, ext, False) == pack.Q_POS_INF
    assert pack.quantize_plane(-math.inf, lo, ext, True) == pack.Q_NEG_INF
    assert pack.quantize_plane(-1e9, lo, ext, False) == 1 and pack.quantize_plane(1e9, lo, ext, True) == 0xFFFE
    step = ext / 0x8000
    for x in np.random.default_rng(0).uniform(lo, lo + ext, 200):
        up = pack.dequantize_plane(pack.quantize_plane(x, lo, ext, True), lo, step)
        down = pack.dequantize_plane(pack.quantize_plane(x, lo, ext, False), lo, step)
        assert x <= up <= x + step and x - step <= down <= x


def test_ess_packed_leaves_are_bricks_exactly():
    rng = np.random.default_rng(6)
    vol = sparse_volume(rng, (30, 41, 37), 6)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.2)
    idx = sc.build_index(vol, tf, "bih")
    assert idx.exact and idx.mode == "ess"
    dec = idx.packed.decode()
    boxes = walk_packed(idx.packed, dec)
    leaves = dec["kind"] == construct.LEAF
    assert np.all(boxes[leaves] % idx.brick == 0)  # planes exact in the padded frame
    occ = tf.classify(*(lambda s: (s.vmin, s.vmax))(vol.brick_stats(8)))
    assert idx.tree.elem_volume[0] == occ.sum() * 8 ** 3
    assert np.isclose(np.prod(boxes[leaves, 3:] - boxes[leaves, :3], axis=1).sum(), occ.sum() * 8 ** 3)


def psnr(a, b):
    mse = float(np.mean((a.astype(np.float64) - b) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1.0 / mse)


@pytest.mark.parametrize("mode", ["single-sample", "multi-sample"])
def test_approximate_modes_close_to_naive(mode):
    """A smooth blob field: BIH-DVR is approximate, but close (catches real breakage)."""
    vol = sc.datasets.nbody_blobs(48, n_clusters=3, blobs_per_cluster=6, seed=2)
    tf = sc.TransferFunction.preset("viridis", vol.value_range)
    cam = sc.Camera.orbit(vol, 35, 25)
    ref = sc.render(vol, tf, cam, 48, 48)
    transparent = sc.TransferFunction([(0, 1, 1, 1, 0), (1, 1, 1, 1, 0)])
    for r in (1.0, 2.0):
        img = sc.render(vol, tf, cam, 48, 48, index="bih", mode=mode, resample=r)
        assert psnr(img.rgba, ref.rgba) > 28
        assert img.stats["samples"] < ref.stats["samples"]
        assert not sc.build_index(vol, tf, "bih", mode=mode, resample=r).exact
        # no opacity, no image
        assert sc.render(vol, transparent, cam, 16, 16, index="bih", mode=mode).rgba.max() == 0
    shaded = sc.render(vol, tf, cam, 32, 32, index="bih", mode=mode, shading=True)
    assert np.isfinite(shaded.rgba).all() and shaded.rgba[..., 3].max() > 0.1


def test_single_sample_opacity_correction():
    """One homogeneous leaf: the single sample's opacity is 1 - (1 - a)^(l / unit)."""
    data = np.zeros((3, 3, 3), np.float32)
    data[1, 1, 1] = 1.0  # one element (threshold 0.9): the cube [0.5, 1.5]^3
    vol = sc.Volume(data)
    a = 0.3
    tf = sc.TransferFunction([(0.0, 1, 1, 1, a), (1.0, 1, 1, 1, a)], unit_distance=1.0)
    cam = sc.Camera.look_at([1.0, -5.0, 1.0], [1.0, 0.0, 1.0], projection="orthographic", ortho_height=0.01)
    img = sc.render(vol, tf, cam, 1, 1, index="bih", mode="single-sample", threshold=0.9, ert=1.0)
    assert img.rgba[0, 0, 3] == pytest.approx(1 - (1 - a) ** 1.0, rel=1e-4)  # one voxel long
    assert img.stats["samples"] == 1


def test_edge_cases_empty_single_identical():
    # empty: no element reaches the threshold -> a tree of 0 nodes, background image
    vol = sc.Volume(np.zeros((6, 7, 8), np.float32))
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    for mode in ("ess", "single-sample", "multi-sample"):
        idx = sc.build_index(vol, tf, "bih", mode=mode)
        assert idx.tree.n_nodes == 0 and idx.packed.nbytes == 0
        img = sc.render(vol, tf, sc.Camera.orbit(vol), 8, 8, index=idx, background="white")
        assert np.array_equal(img.rgba, np.ones_like(img.rgba)) and img.stats["samples"] == 0
    empty = build_bih(make_elements(np.zeros((0, 3)), np.zeros((0, 3))))
    assert empty.n_nodes == 0 and empty.lod().n_nodes == 0 and empty.pack("chunks").nbytes == 0
    # single element: one leaf, exactly its box
    one = build_bih(make_elements([[1.0, 2.0, 3.0]], [[2.0, 2.5, 3.25]]))
    assert one.n_nodes == 1 and one.kind[0] == construct.LEAF
    assert np.array_equal(one.box[0], [1, 2, 3, 2, 2.5, 3.25])
    assert one.pack().decode()["kind"].tolist() == [construct.LEAF]
    # all elements identical: one leaf holding all of them
    same = build_bih(make_elements(np.ones((7, 3)), np.full((7, 3), 2.0)))
    assert same.n_nodes == 1 and same.count[0] == 7
    check_structure(same)
    # constant volume: every voxel an element, all densities equal
    flat = sc.Volume(np.full((5, 5, 5), 3.0, np.float32))
    img = sc.render(flat, tf, sc.Camera.orbit(flat), 8, 8, index="bih", mode="single-sample")
    assert np.isfinite(img.rgba).all()


def test_element_threshold_and_resampling():
    rng = np.random.default_rng(8)
    vol = sparse_volume(rng, (10, 12, 14), 3)
    d = (vol.data - vol.value_range[0]) / (vol.value_range[1] - vol.value_range[0])
    el = voxel_elements(vol, 0.25)
    assert len(el) == int((d >= 0.25).sum())
    assert np.allclose(el.hi - el.lo, 1.0) and el.density.min() >= 0.25 - 1e-9
    el2 = voxel_elements(vol, 0.25, 2.0)
    assert np.allclose(el2.hi - el2.lo, 0.5) and len(el2) > 4 * len(el)
    with pytest.raises(ParameterError, match="resample"):
        voxel_elements(vol, 0.1, 3)
    with pytest.raises(ParameterError, match="threshold"):
        voxel_elements(vol, 1.5)


def test_index_options_rejected():
    vol = sc.Volume(np.zeros((4, 4, 4), np.float32))
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    for kw, word in (({"mode": "fast"}, "mode"), ({"variant": "x"}, "variant"), ({"brick": 1}, "brick"),
                     ({"layout": "bfs"}, "layout"), ({"chunk_depth": 0}, "chunk_depth")):
        with pytest.raises(ParameterError, match=word):
            BIH(vol, tf, **kw)
