"""``vectorize.load_run`` / ``load_window``: a run of adjacent items read as one word gives the items' floats."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit, types

from sparsecast.kernels.vectorize import load_run, load_window, run_loadable


@njit
def _runs4(flat, starts):
    out = np.empty((starts.shape[0], 4))
    for r in range(starts.shape[0]):
        out[r] = load_run(flat, starts[r], 4)
    return out


@njit
def _runs2(flat, starts):
    out = np.empty((starts.shape[0], 2))
    for r in range(starts.shape[0]):
        out[r] = load_run(flat, starts[r], 2)
    return out


@pytest.mark.parametrize("dtype", [np.uint8, np.int8, np.uint16, np.int16, np.uint32, np.int32, np.float32])
def test_runs_are_the_items(dtype):
    rng = np.random.default_rng(7)
    info = np.finfo(dtype) if np.dtype(dtype).kind == "f" else np.iinfo(dtype)
    # extremes (sign bits, all ones) and values at every (unaligned) offset
    flat = np.concatenate([[info.min, info.max, 0], rng.uniform(info.min / 2, info.max / 2, 61)]).astype(dtype)
    starts2 = np.arange(flat.size - 1)
    np.testing.assert_array_equal(_runs2(flat, starts2), flat.astype(np.float64)[starts2[:, None] + np.arange(2)])
    if np.dtype(dtype).itemsize <= 2:
        starts4 = np.arange(flat.size - 3)
        np.testing.assert_array_equal(_runs4(flat, starts4), flat.astype(np.float64)[starts4[:, None] + np.arange(4)])


def test_run_loadable():
    u8 = types.Array(types.uint8, 1, "C")
    assert run_loadable(u8, 8) and not run_loadable(u8, 9)
    assert run_loadable(types.Array(types.uint16, 1, "C"), 4)
    assert not run_loadable(types.Array(types.uint32, 1, "C"), 4)  # 128 bits
    assert run_loadable(types.Array(types.float32, 1, "C"), 2)
    assert not run_loadable(types.Array(types.float64, 1, "C"), 2)
    assert not run_loadable(types.Array(types.uint8, 1, "A"), 2)  # strided views read items one by one
    assert run_loadable(types.Array(types.float32, 2, "C"), 2)  # items in C order


@njit
def _row_pairs(table, i):
    return load_run(table, 4 * i, 2) + load_run(table, 4 * i + 2, 2)


def test_runs_of_a_2d_array_go_in_c_order():
    table = np.random.default_rng(1).random((9, 4)).astype(np.float32)
    for i in range(9):
        assert _row_pairs(table, i) == tuple(float(v) for v in table[i])


@njit
def _windows(flat, starts, skips):
    out = np.empty((starts.shape[0], 2))
    for r in range(starts.shape[0]):
        out[r] = load_window(flat, starts[r], 4, skips[r], 2)
    return out


@pytest.mark.parametrize("dtype", [np.uint8, np.int8, np.uint16, np.int16])
def test_windows_are_the_items_after_the_skip(dtype):
    """Items ``skip, skip + 1`` of a four-item word, every start and every skip (0-2),
    extremes included: a wrong shift or a sign lost shows as another item's value."""
    rng = np.random.default_rng(8)
    info = np.iinfo(dtype)
    flat = np.concatenate([[info.min, info.max, 0, -1 if info.min else 1], rng.integers(info.min, info.max, 40)])
    flat = flat.astype(dtype)
    starts = np.repeat(np.arange(flat.size - 3), 3)
    skips = np.tile(np.arange(3), flat.size - 3)
    want = flat.astype(np.float64)[(starts + skips)[:, None] + np.arange(2)]
    np.testing.assert_array_equal(_windows(flat, starts, skips), want)
