"""``Volume.brick_stats`` against brute force, and its parameter checks.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast import ParameterError, Volume
from reference import trilinear





# ---------------------------------------------------------------------------------
# brick statistics
# ---------------------------------------------------------------------------------
@given(
    shape=st.tuples(st.integers(1, 9), st.integers(1, 9), st.integers(1, 9)),
    brick=st.integers(1, 4),
    seed=st.integers(0, 2**32 - 1),
)
def test_brick_stats_brute_force(shape, brick, seed):
    rng = np.random.default_rng(seed)
    data = (rng.normal(size=shape) * (rng.random(shape) < 0.5)).astype(np.float32)
    vol = Volume(data)
    bs = vol.brick_stats(brick)
    assert bs.brick_size == brick
    nb = tuple(max(1, -(-(n - 1) // brick)) for n in shape)
    assert bs.shape == nb
    assert vol.brick_stats(brick) is bs  # cached
    for bk in range(nb[0]):
        for bj in range(nb[1]):
            for bi in range(nb[2]):
                sl = tuple(
                    slice(max(b * brick - 1, 0), min((b + 1) * brick + 1, n - 1) + 1)
                    for b, n in zip((bk, bj, bi), shape)
                )
                block = data[sl].astype(np.float64)
                assert bs.vmin[bk, bj, bi] == block.min()
                assert bs.vmax[bk, bj, bi] == block.max()
                # trilinear samples anywhere inside the brick stay within its range
                lo = np.array([bi, bj, bk], np.float64) * brick
                hi = np.minimum(lo + brick, np.array(shape[::-1], np.float64) - 1)
                pts = lo + (hi - lo) * rng.random((64, 3))
                pts[:8] = lo + (hi - lo) * np.array(np.meshgrid([0, 1], [0, 1], [0, 1])).reshape(3, -1).T
                v = trilinear(data, pts[:, 0], pts[:, 1], pts[:, 2])
                eps = 1e-12 * max(1.0, abs(block).max())
                assert v.min() >= bs.vmin[bk, bj, bi] - eps
                assert v.max() <= bs.vmax[bk, bj, bi] + eps


def test_brick_stats_bad_size(small):
    with pytest.raises(ParameterError, match="brick_size"):
        small[0].brick_stats(0)



def test_brick_larger_than_the_volume_is_one_brick():
    """A huge brick size (``info --brick-size 1000000``) is one brick, not a padded 13 PiB array."""
    data = np.arange(5 * 6 * 7, dtype=np.float32).reshape(5, 6, 7)
    bs = Volume(data).brick_stats(1_000_000)
    assert bs.shape == (1, 1, 1)
    assert bs.vmin[0, 0, 0] == data.min() and bs.vmax[0, 0, 0] == data.max()


def test_brick_kernel_warm_up_compiles_what_the_real_pass_runs(monkeypatch):
    """The first brick_stats compiles on a tiny array first (kept out of build_ms): that array
    must have the Numba type of a Volume's voxels, read-only flag included, and the warm-up
    must compile what the threaded slabs run, or the real pass compiles again inside the
    timing."""
    import numba

    from sparsecast import volume as volume_module
    from sparsecast.kernels import bricks
    from sparsecast.kernels.windows import window_minmax

    monkeypatch.setattr(bricks, "TASK_BYTES", 256)  # slabs on two threads
    data = np.arange(40 * 30 * 20, dtype=np.int16).reshape(40, 30, 20)
    vol = Volume(data)
    assert numba.typeof(volume_module._tiny_voxels(vol.dtype)) == numba.typeof(vol.data)
    monkeypatch.setattr(volume_module, "_WARM_DTYPES", set())
    assert volume_module._warm_brick_kernel(vol.dtype) > 0
    warm = set(window_minmax.signatures)
    assert numba.typeof(vol.data[3:9]) in {sig[0] for sig in warm}
    stats = vol.brick_stats(4)
    assert stats.compile_ms == 0.0  # once per dtype and process
    assert set(window_minmax.signatures) == warm  # the real pass compiled nothing
    ref = [np.empty(stats.shape), np.empty(stats.shape)]
    bricks.brick_minmax(vol.data, 4, *stats.shape, *ref)
    np.testing.assert_array_equal(stats.vmin, ref[0])
    np.testing.assert_array_equal(stats.vmax, ref[1])


# -- per-brick label sets (issue 19, label volumes) -------------------------------------
def _brute_sets(data, b):
    nz, ny, nx = data.shape
    nb = [max(1, -(-(n - 1) // b)) for n in data.shape]
    out = {}
    for k in range(nb[0]):
        for j in range(nb[1]):
            for i in range(nb[2]):
                win = data[max(k * b - 1, 0):min((k + 1) * b + 1, nz - 1) + 1,
                           max(j * b - 1, 0):min((j + 1) * b + 1, ny - 1) + 1,
                           max(i * b - 1, 0):min((i + 1) * b + 1, nx - 1) + 1]
                out[k, j, i] = set(np.unique(win).tolist())
    return out


@pytest.mark.parametrize("dtype", ["uint8", "int16", "float32"])
@pytest.mark.parametrize("brick", [4, 8, 16])
def test_brick_labels_equal_the_ids_of_each_apron_window(dtype, brick):
    rng = np.random.default_rng(5)
    data = np.zeros((37, 21, 50), dtype)
    for label in (3, 9, 70, 71):
        z, y, x = (int(rng.integers(0, n - 4)) for n in data.shape)
        data[z:z + 5, y:y + 9, x:x + 3] = label if dtype != "int16" else label - 40
    vol = sc.Volume(data)
    sets = vol.brick_labels(brick)
    assert sets is vol.brick_labels(brick)  # cached
    assert sets.words.shape[:3] == vol.brick_stats(brick).shape
    for (k, j, i), want in _brute_sets(data, brick).items():
        got = {int(sets.ids[r]) for r in range(len(sets.ids))
               if sets.words[k, j, i, r // 64] >> np.uint64(r % 64) & np.uint64(1)}
        assert got == want, (k, j, i)


def test_brick_labels_are_none_for_fields():
    rng = np.random.default_rng(0)
    assert sc.Volume(rng.random((9, 9, 9)).astype(np.float32)).brick_labels() is None
    many = np.arange(20 * 20 * 20, dtype=np.uint16).reshape(20, 20, 20)  # 8000 distinct values
    assert sc.Volume(many).brick_labels() is None


def test_rank_words_ignore_ids_the_volume_lacks():
    data = np.zeros((10, 10, 10), np.uint8)
    data[2:5, 2:5, 2:5] = 7
    sets = sc.Volume(data).brick_labels()
    assert list(sets.ids) == [0, 7]
    assert sets.rank_words([7, 9, 200]).tolist() == [2]
    assert sets.rank_words([]).tolist() == [0]
