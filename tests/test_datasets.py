"""Generated data (sparsecast.datasets): deterministic, sparse, the shapes and dtypes asked for."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc


def test_nbody_blobs_is_deterministic_and_sparse():
    a = sc.datasets.nbody_blobs(48, seed=7)
    b = sc.datasets.nbody_blobs(48, seed=7)
    c = sc.datasets.nbody_blobs(48, seed=8)
    assert np.array_equal(a.data, b.data)
    assert not np.array_equal(a.data, c.data)
    assert a.data.dtype == np.float32
    assert a.value_range[0] == 0.0 and a.value_range[1] == pytest.approx(1.0)
    tf = sc.TransferFunction.preset("viridis", a.value_range)
    bricks = a.brick_stats(8)
    occupancy = tf.classify(bricks.vmin, bricks.vmax).mean()
    assert 0.01 < occupancy < 0.6


def test_nbody_blobs_non_cubic_and_uint8():
    v = sc.datasets.nbody_blobs((40, 30, 20), dtype=np.uint8, n_clusters=3)
    assert v.shape == (20, 30, 40) and v.dtype == np.uint8
    assert v.data.max() == 255


def test_sphere_shell_is_hollow():
    v = sc.datasets.sphere_shell(33)
    assert v.data[16, 16, 16] == 0.0
    assert v.data.max() == 1.0


def test_random_clusters_balls():
    v = sc.datasets.random_clusters(32, 3, 4.0, seed=1)
    assert v.shape == (32, 32, 32) and v.dtype == np.float32
    inside = v.data[v.data > 0]
    assert inside.size and inside.min() >= 0.2 and inside.max() <= 1.0
    # Three balls of radius 4 hold at most 3 * 257 voxels (the lattice points of one ball).
    assert inside.size <= 3 * 257
    assert np.array_equal(v.data, sc.datasets.random_clusters(32, 3, 4.0, seed=1).data)


def test_volume_does_not_freeze_the_callers_array():
    arr = np.zeros((3, 4, 5), np.float32)
    vol = sc.Volume(arr)
    assert arr.flags.writeable          # the caller's array is untouched...
    assert not vol.data.flags.writeable  # ...the volume's view is read-only
    assert np.shares_memory(arr, vol.data)  # and nothing was copied
