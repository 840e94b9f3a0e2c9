"""The cell bound (bench.bounds): the naive marcher's samples, counted by where they fall."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.bench.bounds import cell_bound, cell_occupancy
from sparsecast.datasets import nbody_blobs
from sparsecast.transfer import TransferFunction


@pytest.fixture(scope="module")
def scene():
    vol = nbody_blobs(24, n_clusters=3, blobs_per_cluster=5, dtype=np.uint8)
    vol = sc.Volume(vol.data, spacing=(1.0, 1.5, 0.75))  # anisotropic: index space is not world space
    return vol, TransferFunction.preset("viridis", vol.value_range, threshold=0.3)


CAMERAS = {
    "oblique": dict(azimuth=30.0, elevation=20.0),
    "axis": dict(azimuth=0.0, elevation=0.0, projection="orthographic"),
    "inside": dict(azimuth=45.0, elevation=10.0, distance=2.0),  # eye inside the box
}


@pytest.mark.parametrize("view", sorted(CAMERAS))
def test_counts_are_the_naive_marchers_and_bracket_the_oracle(scene, view):
    vol, tf = scene
    cam = sc.Camera.orbit(vol, **CAMERAS[view])
    img = sc.render(vol, tf, cam, 24, 20, index="naive")
    b = cell_bound(vol, tf, cam, 24, 20, img.stats["dt"], img.stats["ert"])
    # Same lattice and same early termination as the driver: the same counts.
    assert b["samples"] == img.stats["samples"] > 0
    assert b["samples_nonempty"] == img.stats["samples_nonempty"] > 0
    # Every visible sample lies in an occupied cell; some samples in occupied cells are not visible.
    assert b["samples_nonempty"] <= b["samples_cell_bound"] <= b["samples"]
    assert b["samples_cell_bound"] < b["samples"]


def test_occupancy_covers_every_visible_value_of_a_cell():
    rng = np.random.default_rng(4)
    data = rng.integers(0, 256, (5, 6, 7)).astype(np.uint8)
    tf = TransferFunction.preset("viridis", (0.0, 255.0), threshold=0.6)
    table = tf.opacity_table(0.5, 1.0)
    occ = cell_occupancy(data, table, 0.0, tf.scale)
    assert occ.shape == (4, 5, 6)
    from sparsecast.kernels.shade import tf_alpha
    from sparsecast.kernels.sample import trilinear
    flat = data.reshape(-1)
    for _ in range(3000):
        x, y, z = rng.random(3) * (6, 5, 4)
        a = tf_alpha(table, trilinear(flat, 7, 6, 5, x, y, z), 0.0, tf.scale)[2]
        if a > 0.0:
            assert occ[int(z), int(y), int(x)]
    # Nothing visible: nothing occupied; everything visible: every cell.
    none = TransferFunction([(0.0, 0, 0, 0, 0.0), (255.0, 0, 0, 0, 0.0)], (0.0, 255.0))
    assert not cell_occupancy(data, none.opacity_table(0.5, 1.0), 0.0, none.scale).any()
    full = TransferFunction([(0.0, 1, 1, 1, 0.5), (255.0, 1, 1, 1, 0.5)], (0.0, 255.0))
    assert cell_occupancy(data, full.opacity_table(0.5, 1.0), 0.0, full.scale).all()


def test_label_tfs_have_no_cell_bound(scene):
    vol, _ = scene
    labels = TransferFunction.labels({1: (1, 0, 0, 1)})
    assert cell_bound(vol, labels, sc.Camera.orbit(vol), 4, 4, 0.5) is None


def test_a_kept_occupancy_gives_the_same_counts(scene):
    from sparsecast.bench.bounds import volume_occupancy

    vol, tf = scene
    cam = sc.Camera.orbit(vol, 30.0, 20.0)
    dt = 0.375
    kept = volume_occupancy(vol, tf, dt)
    assert cell_bound(vol, tf, cam, 16, 12, dt, occupancy=kept) == cell_bound(vol, tf, cam, 16, 12, dt)
