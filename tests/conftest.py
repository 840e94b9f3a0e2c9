"""Shared pytest fixtures and the hypothesis profile for the sparsecast tests."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# Keep property tests quick and free of timing flakiness (Numba compiles on first use).
settings.register_profile("ci", max_examples=25, deadline=None)
settings.load_profile("ci")

#: the environment variable naming the folder of real data (as for the benchmarks)
DATA_VARIABLE = "SPARSECAST_DATA"

#: ``$SPARSECAST_DATA``, else ``../shared/data`` beside the project root; absent in a fresh clone.
SHARED_DATA_DIR = (Path(os.environ[DATA_VARIABLE]) if os.environ.get(DATA_VARIABLE)
                   else Path(__file__).resolve().parents[1].parent / "shared" / "data")


@pytest.fixture(scope="session")
def shared_data_dir() -> Path:
    """Directory of real public data (may not exist: use :func:`shared_file`, which skips then)."""
    return SHARED_DATA_DIR


@pytest.fixture(scope="session")
def shared_file():
    """``shared_file(NAME)``: the path of a real-data file, or a skip that says where it was
    looked for and how to point the tests at it."""

    def find(name: str) -> Path:
        path = SHARED_DATA_DIR / name
        if not path.is_file():
            pytest.skip(f"real data {name} not found in {SHARED_DATA_DIR}: set {DATA_VARIABLE} to the folder "
                        f"holding it (README, 'Tests and real data')")
        return path

    return find


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded random generator, fresh for every test."""
    return np.random.default_rng(20240611)


@pytest.fixture(scope="module")
def small():
    """A 12^3 random float32 volume, a viridis TF and an orbit camera (for quick checks)."""
    from render_helpers import random_volume
    import sparsecast as sc

    rng = np.random.default_rng(3)
    vol = random_volume(rng, (12, 12, 12), "float32")
    return vol, sc.TransferFunction.preset("viridis", (0.0, 1.0)), sc.Camera.orbit(vol, 30, 20)
