"""Generated volumes and the benchmark dataset registry."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.bench.datasets import DATASETS, find_shared_data


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


def test_find_shared_data_honours_env(monkeypatch, tmp_path):
    monkeypatch.setenv("SPARSECAST_DATA", str(tmp_path))
    assert find_shared_data() == tmp_path.resolve()


def test_registry_demo_is_always_available():
    assert DATASETS["demo"].available()
    assert "mni152" in DATASETS


def test_shared_dataset_skips_cleanly_without_data(monkeypatch, tmp_path):
    monkeypatch.setenv("SPARSECAST_DATA", str(tmp_path))  # an empty folder
    assert not DATASETS["mni152"].available()


def test_volume_does_not_freeze_the_callers_array():
    arr = np.zeros((3, 4, 5), np.float32)
    vol = sc.Volume(arr)
    assert arr.flags.writeable          # the caller's array is untouched...
    assert not vol.data.flags.writeable  # ...the volume's view is read-only
    assert np.shares_memory(arr, vol.data)  # and nothing was copied
