"""Fixtures shared by the command-line tests."""

from __future__ import annotations

import pytest

import sparsecast as sc


@pytest.fixture
def small_volume_file(tmp_path):
    vol = sc.datasets.nbody_blobs(24, n_clusters=2, blobs_per_cluster=6, seed=3)
    path = tmp_path / "blobs.npy"
    sc.save_volume(vol, path)
    return path
