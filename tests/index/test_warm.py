"""First-use compilation of an index build is done on a tiny volume and kept out of build_ms."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.index import warm
from sparsecast.index.warm import tiny_volume


@pytest.mark.parametrize("dtype", ["uint8", "uint16", "int16", "float32", "float64"])
def test_tiny_volume_spans_the_range_with_empty_space(dtype):
    vol = tiny_volume(np.dtype(dtype), (0.0, 200.0))
    assert vol.dtype == np.dtype(dtype) and vol.shape == (warm.TINY,) * 3
    assert vol.value_range[0] == 0.0 and 180.0 < vol.value_range[1] <= 200.0  # blob peaks between voxels
    assert 0.01 < np.mean(vol.data > 0) < 0.5  # blobs in exact empty space: the indices skip some


def test_uint8_range_is_clipped():
    vol = tiny_volume(np.dtype("uint8"), (0.0, 4095.0))
    assert vol.value_range == (0.0, 255.0)


def test_build_index_warms_once_per_index_and_dtype(monkeypatch):
    monkeypatch.setattr(warm, "_WARM", set())
    vol = sc.datasets.nbody_blobs(20, n_clusters=2, blobs_per_cluster=3, seed=1, dtype=np.float32)
    tf = sc.TransferFunction.preset("viridis", value_range=vol.value_range)
    first = sc.build_index(vol, tf, "grid-pc")
    assert first.compile_ms > 0 and first.stats()["compile_ms"] == first.compile_ms
    second = sc.build_index(vol, tf, "grid-pc")
    assert second.compile_ms == 0.0
    assert sc.build_index(vol, tf, "grid-pc", cell=8).compile_ms > 0  # other options: other kernels maybe
    vol8 = sc.Volume((vol.data / vol.data.max() * 255).astype(np.uint8))
    assert sc.build_index(vol8, sc.TransferFunction.preset("viridis", (0, 255)), "grid-pc").compile_ms > 0
    img = sc.render(vol, tf, sc.Camera.orbit(vol), 8, 8, index="lbvh")
    assert img.stats["jit_ms"] > 0 and img.stats["build_ms"] >= 0  # lbvh was not warm: counted in jit_ms


def test_warm_up_failure_leaves_the_error_to_the_real_build(monkeypatch):
    monkeypatch.setattr(warm, "_WARM", set())
    vol = sc.datasets.nbody_blobs(20, seed=1)
    tf = sc.TransferFunction.preset("viridis", value_range=vol.value_range)
    with pytest.raises(sc.ParameterError, match="cell"):
        sc.build_index(vol, tf, "grid-pc", cell=5)
    assert not warm._WARM


@pytest.mark.parametrize("name", ["kdtree-deep", "bih"])
def test_the_timed_build_compiles_nothing_after_the_warm_up(monkeypatch, name):
    """Checked on a cold kernel cache (after a kernel edit), trivially on a warm one."""
    from sparsecast import kernel_cache
    from sparsecast.index.registry import index_class

    monkeypatch.setattr(warm, "_WARM", set())
    vol = sc.datasets.nbody_blobs(28, n_clusters=3, blobs_per_cluster=4, seed=2, dtype=np.uint16)
    tf = sc.TransferFunction.preset("bone", value_range=vol.value_range)
    warm.warm_build(index_class(name), vol, tf, {})
    before = kernel_cache.compile_seconds()
    index_class(name)(vol, tf)
    assert kernel_cache.compile_seconds() == before


def test_label_tf_warms_on_a_label_volume(monkeypatch):
    """A label TF classifies bricks by their id sets: the warm-up volume holds its visible
    ids, so the label kernels compile there, not in the timed build."""
    from sparsecast import kernel_cache
    from sparsecast.index.registry import index_class

    vol = tiny_volume(np.dtype("uint8"), (0.0, 9.0), labels=(4, 9))
    assert set(np.unique(vol.data).tolist()) == {0, 4, 9}
    monkeypatch.setattr(warm, "_WARM", set())
    data = np.zeros((30, 30, 30), np.uint8)
    data[3:12, 5:20, 4:9] = 7
    data[15:25, 2:8, 10:28] = 3
    real = sc.Volume(data)
    tf = sc.TransferFunction.labels([3, 7])
    warm.warm_build(index_class("kdtree-deep"), real, tf, {})
    before = kernel_cache.compile_seconds()
    idx = sc.build_index(real, tf, "kdtree-deep")
    assert kernel_cache.compile_seconds() == before and idx.compile_ms == 0.0
