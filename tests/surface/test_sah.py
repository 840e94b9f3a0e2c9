"""The parallel binned-SAH builder: a valid tree, the same tree on any number of threads."""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast.surface.sah import PARALLEL_MIN, build_sah


def _boxes(rng, m):
    c = rng.normal(size=(m, 3)) * [1.0, 0.5, 2.0]
    half = rng.uniform(0.0, 0.05, (m, 3))
    return (c - half).astype(np.float32), (c + half).astype(np.float32)


def _check_tree(nb, child, count, ids, lo, hi, max_leaf):
    """Every primitive in one leaf, boxes nested, leaves within the SAH's size limit."""
    m = len(lo)
    assert sorted(ids.tolist()) == list(range(m))
    seen = np.zeros(m, np.int64)
    stack = [0]
    while stack:
        k = stack.pop()
        if count[k] > 0:
            assert count[k] <= 4 * max_leaf
            r = ids[child[k]:child[k] + count[k]]
            seen[r] += 1
            assert np.all(nb[k, 0] <= lo[r]) and np.all(hi[r] <= nb[k, 1])
        else:
            for c in (child[k], child[k] + 1):
                assert c > k and np.all(nb[k, 0] <= nb[c, 0]) and np.all(nb[c, 1] <= nb[k, 1])
                stack.append(c)
    assert np.all(seen == 1)
    np.testing.assert_array_equal(nb[0, 0], lo.min(0))
    np.testing.assert_array_equal(nb[0, 1], hi.max(0))


@pytest.mark.parametrize("max_leaf", [1, 4])
def test_parallel_build_is_valid_and_equals_the_serial_one(rng, max_leaf):
    lo, hi = _boxes(rng, 3 * PARALLEL_MIN)
    serial = build_sah(lo, hi, max_leaf, threads=1)
    parallel = build_sah(lo, hi, max_leaf, threads=3)
    assert serial.threads == 1 and parallel.threads == 3
    flat = parallel.flatten()
    _check_tree(*flat, parallel.ids, lo, hi, max_leaf)
    for a, b in zip(serial.flatten(), flat):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(serial.ids, parallel.ids)
    assert serial.depth == parallel.depth
    # The SAH keeps the tree shallow on well-spread boxes.
    assert parallel.depth < 4 * np.log2(len(lo))


def test_coincident_centroids_split_by_position(rng):
    # No bin border separates anything: the builder halves the list instead.
    m = PARALLEL_MIN + 100
    lo = np.zeros((m, 3), np.float32)
    hi = np.ones((m, 3), np.float32)
    tree = build_sah(lo, hi, 4, threads=2)
    nb, child, count = tree.flatten()
    _check_tree(nb, child, count, tree.ids, lo, hi, 4)
    assert tree.depth <= int(np.ceil(np.log2(m / 4))) + 2


def test_a_single_primitive_is_a_leaf():
    tree = build_sah(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    nb, child, count = tree.flatten()
    assert len(count) == 1 and count[0] == 1 and child[0] == 0 and tree.depth == 1
