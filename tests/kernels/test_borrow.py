"""Borrowed views keep values and memory, and take no references; the lattice march is
compiled once for every index (kernels.borrow, index.interval "Inlining")."""

from __future__ import annotations

import sys
from typing import NamedTuple

import numpy as np
from numba import njit

import sparsecast as sc
from sparsecast.kernels.borrow import borrowed
from sparsecast.kernels.march import march_interval
from sparsecast.render import driver, local
from synthetic import sparse_volume


class _Inner(NamedTuple):
    weights: np.ndarray
    gain: float


class _Outer(NamedTuple):
    ids: np.ndarray
    grid: np.ndarray
    count: int
    flag: bool
    inner: _Inner
    pair: tuple


@njit
def _read_and_write(rec, n):
    # Reads every member through the borrowed record many times (a refcount bug
    # would show as a crash or a changed count), and writes through one view.
    b = borrowed(rec)
    total = 0.0
    for _ in range(n):
        total += b.ids[1] + b.grid[1, 2, 0] + b.inner.weights[0] * b.inner.gain + b.pair[0][0] + b.pair[1]
        total += b.count + (1.0 if b.flag else 0.0)
    b.grid[0, 0, 0] = 42.0
    b.pair[0][1] = -7.0
    return total, b.ids.shape[0], b.grid.shape, b.inner.weights.itemsize


def test_borrowed_record_reads_values_and_shares_memory():
    rec = _Outer(
        ids=np.arange(5, dtype=np.int32),
        grid=np.arange(24, dtype=np.float64).reshape(2, 3, 4),
        count=3,
        flag=True,
        inner=_Inner(np.array([0.5, 2.0], np.float32), 4.0),
        pair=(np.array([1.5, 2.5]), 10.0),
    )
    before = [sys.getrefcount(a) for a in (rec.ids, rec.grid, rec.inner.weights, rec.pair[0])]
    total, n_ids, shape, itemsize = _read_and_write(rec, 1000)
    one = rec.ids[1] + rec.grid[1, 2, 0] + rec.inner.weights[0] * rec.inner.gain + rec.pair[0][0] + rec.pair[1] + 3 + 1.0
    assert total == 1000 * one
    assert (n_ids, shape, itemsize) == (5, (2, 3, 4), 4)
    # The views alias the caller's arrays ...
    assert rec.grid[0, 0, 0] == 42.0 and rec.pair[0][1] == -7.0
    # ... and left no reference behind, and took none away.
    after = [sys.getrefcount(a) for a in (rec.ids, rec.grid, rec.inner.weights, rec.pair[0])]
    assert after == before


def test_march_interval_is_one_copy_for_every_index(monkeypatch):
    """The lattice march's signature names no record: rendering with a second index of
    the same voxel dtype and sampler compiles no new copy of it.

    The driver runs uncached here, so that it is typed in this process (a driver
    loaded from the disk cache never asks for ``march_interval`` by name)."""
    monkeypatch.setattr(local, "tiles_kernel", lambda record: driver.dvr_tiles_uncached)
    vol = sparse_volume(np.random.default_rng(3), (20, 20, 20), 4)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    cam = sc.Camera.orbit(vol, 30, 20)
    sc.render(vol, tf, cam, 8, 8, index=sc.build_index(vol, tf, "naive"))
    after_first = set(march_interval.signatures)
    assert after_first, "the driver no longer calls march_interval as a function"
    for kind in ("grid-mm", "lbvh"):
        sc.render(vol, tf, cam, 8, 8, index=sc.build_index(vol, tf, kind))
        assert set(march_interval.signatures) == after_first, kind
