"""Iterative range tree (Wald 2019): range maxima against brute force, TF emptiness against
the prefix count, bad input, and the benchmark helper's records."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparsecast.bench.range_tree import (
    RangeMaxTree,
    classify_irt,
    is_empty_irt,
    level_layout,
    opacity_range_tree,
    range_max,
)
from sparsecast.errors import ParameterError
from sparsecast.transfer import TransferFunction

# Sizes that exercise every odd/even level pattern, plus random ones up to 5000.
_EDGE_SIZES = [1, 2, 3, 4, 5, 7, 8, 9, 255, 256, 257, 1023, 1025, 4097, 5000]
sizes = st.one_of(st.sampled_from(_EDGE_SIZES), st.integers(1, 5000))


@st.composite
def array_and_ranges(draw):
    n = draw(sizes)
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["uniform", "sparse", "ties", "f32"]))
    if kind == "uniform":
        v = rng.uniform(-1.0, 1.0, n)
    elif kind == "sparse":  # mostly zeros, like a TF opacity column
        v = np.where(rng.random(n) < 0.05, rng.random(n), 0.0)
    elif kind == "ties":
        v = rng.integers(0, 3, n).astype(np.float64)
    else:
        v = rng.random(n).astype(np.float32)
    lo = rng.integers(0, n, 64)
    hi = rng.integers(0, n, 64)
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    # Always include the whole array, single entries at both ends and a short range at the end.
    lo = np.concatenate([lo, [0, 0, n - 1, max(n - 3, 0)]])
    hi = np.concatenate([hi, [n - 1, 0, n - 1, n - 1]])
    return v, lo, hi


@given(array_and_ranges())
def test_query_matches_brute_force(case):
    v, lo, hi = case
    tree = RangeMaxTree(v)
    for a, b in zip(lo.tolist(), hi.tolist()):
        assert tree.query(a, b) == v[a:b + 1].max()


@given(array_and_ranges())
def test_query_many_matches_query(case):
    v, lo, hi = case
    tree = RangeMaxTree(v)
    got = tree.query_many(lo, hi)
    assert got.dtype == tree.flat.dtype
    expect = np.array([tree.query(a, b) for a, b in zip(lo.tolist(), hi.tolist())])
    np.testing.assert_array_equal(got, expect)
    np.testing.assert_array_equal(got, [v[a:b + 1].max() for a, b in zip(lo, hi)])


def test_every_range_small_arrays():
    rng = np.random.default_rng(1)
    for n in range(1, 40):
        v = rng.random(n)
        tree = RangeMaxTree(v)
        lo, hi = np.triu_indices(n)
        np.testing.assert_array_equal(tree.query_many(lo, hi), [v[a:b + 1].max() for a, b in zip(lo, hi)])


def test_levels_layout_and_values():
    v = np.array([3.0, 1.0, 4.0, 1.0, 5.0, 9.0, 2.0])
    tree = RangeMaxTree(v)
    np.testing.assert_array_equal(tree.sizes, [7, 4, 2, 1])
    np.testing.assert_array_equal(tree.offsets, [0, 7, 11, 13])
    np.testing.assert_array_equal(tree.level(0), v)
    np.testing.assert_array_equal(tree.level(1), [3, 4, 9, 2])
    np.testing.assert_array_equal(tree.level(2), [4, 9])
    np.testing.assert_array_equal(tree.level(3), [9])
    assert tree.flat.shape == (14,) and tree.levels == 4
    assert tree.offsets.dtype == np.int64 and tree.sizes.dtype == np.int64
    assert tree.nbytes == tree.flat.nbytes + 2 * 4 * 8
    assert tree.build_ms >= 0
    assert not tree.flat.flags.writeable
    offs, szs = level_layout(1)
    assert offs.tolist() == [0] and szs.tolist() == [1]


def test_dtype_kept():
    assert RangeMaxTree(np.zeros(5, np.float32)).flat.dtype == np.float32
    assert RangeMaxTree(np.zeros(5, np.float64)).flat.dtype == np.float64
    assert RangeMaxTree(np.arange(5)).flat.dtype == np.float64


def test_clamping():
    v = np.array([0.1, 0.7, 0.3])
    tree = RangeMaxTree(v)
    assert tree.query(-10, 0) == 0.1
    assert tree.query(2, 99) == 0.3
    assert tree.query(-5, 99) == 0.7
    assert tree.query(5, 9) == 0.3  # entirely above: clamps to the last entry
    np.testing.assert_array_equal(tree.query_many([-3, 1], [0, 50]), [0.1, 0.7])


def test_range_max_empty_span_is_minus_inf():
    tree = RangeMaxTree([1.0, 2.0, 3.0])
    assert range_max(tree.flat, tree.offsets, tree.sizes, 2, 1) == -np.inf


def test_bad_input_raises():
    tree = RangeMaxTree([0.0, 1.0, 2.0])
    with pytest.raises(ParameterError, match="lo <= hi"):
        tree.query(2, 1)
    with pytest.raises(ParameterError, match="lo <= hi"):
        tree.query_many([0, 2], [1, 1])
    with pytest.raises(ParameterError, match="integer"):
        tree.query(0.5, 1)
    with pytest.raises(ParameterError, match="integer"):
        tree.query_many(np.array([0.0]), np.array([1.0]))
    with pytest.raises(ParameterError, match="1-D"):
        RangeMaxTree(np.zeros((2, 2)))
    with pytest.raises(ParameterError, match="at least one"):
        RangeMaxTree([])
    with pytest.raises(ParameterError, match="finite"):
        RangeMaxTree([0.0, np.nan])
    with pytest.raises(ParameterError, match="level"):
        tree.level(7)
    assert issubclass(ParameterError, ValueError)


# -- transfer functions ------------------------------------------------------------
@st.composite
def tf_and_ranges(draw):
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    table_size = draw(st.sampled_from([256, 1024, 4096]))
    lo = float(rng.uniform(-1e3, 1e3))
    span = float(10.0 ** rng.uniform(-3, 4))
    k = int(rng.integers(1, 12))
    xs = np.sort(rng.uniform(lo, lo + span, k))
    if k > 2 and rng.random() < 0.3:
        xs[1] = xs[0]  # a step
    # Opacity: mostly zero with some bumps, so both answers occur often.
    alpha = np.where(rng.random(k) < 0.5, 0.0, rng.random(k))
    pts = np.column_stack([xs, rng.random((k, 3)), alpha])
    vr = (lo, lo + span) if rng.random() < 0.7 else None
    tf = TransferFunction(pts, vr, table_size=table_size)
    v0, v1 = tf.value_range
    w = v1 - v0
    m = 256
    a = rng.uniform(v0 - 0.5 * w, v1 + 0.5 * w, m)  # includes ranges wholly outside
    width = np.where(rng.random(m) < 0.5, rng.exponential(w / table_size * 3, m), rng.uniform(0, w, m))
    b = a + width
    # Boundary-hugging ranges: exactly on table entries and a hair around them.
    e = rng.integers(0, table_size, 32) / tf.scale + v0
    a = np.concatenate([a, e, e - 1e-9 * w, [v0 - 2 * w, v1 + w, v0, v1]])
    b = np.concatenate([b, e, e + 1e-9 * w, [v0 - w, v1 + 2 * w, v0, v1]])
    return tf, a, b


@given(tf_and_ranges())
def test_irt_classify_matches_prefix_count(case):
    tf, vmin, vmax = case
    tree = opacity_range_tree(tf)
    assert tree.size == tf.table_size
    got = classify_irt(tree, tf, vmin, vmax)
    np.testing.assert_array_equal(got, tf.classify(vmin, vmax))
    np.testing.assert_array_equal(is_empty_irt(tree, tf, vmin, vmax), ~got)
    # Same entry spans as tf._entry_span, and max opacity > 0 there.
    first, last = tf._entry_span(vmin, vmax)
    alpha = tf.table[:, 3]
    np.testing.assert_array_equal(tree.query_many(first, last) > 0, got)
    for i in range(0, len(vmin), 37):
        assert tree.query(int(first[i]), int(last[i])) == alpha[first[i]:last[i] + 1].max()
        assert is_empty_irt(tree, tf, vmin[i], vmax[i]) == tf.is_empty(vmin[i], vmax[i])


def test_irt_classify_shapes_and_errors():
    tf = TransferFunction([(0, 0, 0, 0, 0), (0.5, 0, 0, 0, 0), (1, 1, 1, 1, 1)], table_size=256)
    tree = opacity_range_tree(tf)
    vmin = np.array([[0.0, 0.1], [0.6, 2.0]])
    vmax = vmin + 0.05
    got = classify_irt(tree, tf, vmin, vmax)
    assert got.shape == (2, 2) and got.dtype == np.bool_
    np.testing.assert_array_equal(got, tf.classify(vmin, vmax))
    assert is_empty_irt(tree, tf, 0.0, 0.2) is True
    assert is_empty_irt(tree, tf, 0.0, 0.9) is False
    other = TransferFunction([(0, 0, 0, 0, 0), (1, 1, 1, 1, 1)], table_size=512)
    with pytest.raises(ParameterError, match="table_size"):
        classify_irt(tree, other, vmin, vmax)
    with pytest.raises(ParameterError, match="finite"):
        classify_irt(tree, tf, [np.nan], [1.0])


@settings(max_examples=5)
@given(st.sampled_from(["grayscale", "bone", "viridis"]), st.sampled_from([256, 1024, 4096]))
def test_irt_presets(name, table_size):
    tf = TransferFunction.preset(name, (-100.0, 300.0), table_size=table_size)
    tree = opacity_range_tree(tf)
    rng = np.random.default_rng(table_size)
    a = rng.uniform(-150, 350, 2000)
    b = a + rng.exponential(5.0, 2000)
    np.testing.assert_array_equal(classify_irt(tree, tf, a, b), tf.classify(a, b))


# -- benchmark helper ------------------------------------------------------------
def test_irt_build_times_records():
    from sparsecast.bench.irt import irt_build_times

    recs = irt_build_times(sizes=(256, 1024), repeat=2, n_queries=1000)
    phases = {(r["phase"], r["table_size"]) for r in recs}
    assert phases == {(p, n) for p in ("irt_build", "irt_query", "prefix_query") for n in (256, 1024)}
    for r in recs:
        assert r["ms"] > 0 and r["bytes"] > 0
        assert len(r["ms_runs"]) == 2
    assert all(r["agree"] for r in recs if r["phase"] == "irt_query")
    assert all(r["queries"] == 1000 for r in recs if r["phase"] != "irt_build")
