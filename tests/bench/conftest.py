"""A tiny benchmark dataset, registered for the duration of a test."""

from __future__ import annotations

import pytest

from sparsecast.bench import DATASETS, BenchDataset
from sparsecast.bench.config import BenchConfig
from sparsecast.datasets import nbody_blobs
from sparsecast.transfer import TransferFunction


@pytest.fixture
def tiny_dataset(monkeypatch) -> str:
    """Name of a 24^3 sparse-blob dataset in :data:`DATASETS` (removed afterwards)."""
    monkeypatch.setitem(DATASETS, "tiny", BenchDataset(
        "tiny", "24^3 blobs for tests",
        lambda: nbody_blobs(24, n_clusters=2, blobs_per_cluster=6, seed=3),
        lambda v: TransferFunction.preset("viridis", v.value_range),
        default=False,
    ))
    return "tiny"


@pytest.fixture
def tiny_config(tiny_dataset) -> BenchConfig:
    """Two methods, two sizes, two views, one timed run each: 2 x (2 + 2 x 2) render/build cases per TF."""
    return BenchConfig(datasets=[tiny_dataset], methods=["naive", "grid-pc"], sizes=[(16, 16), (12, 8)],
                       views=[(30.0, 20.0), (0.0, 90.0)], repeat=1, warmup=0, irt=False)
