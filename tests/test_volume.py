"""``Volume.brick_stats`` against brute force, and its parameter checks.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

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
    must have the Numba type of a Volume's voxels, read-only flag included, or the real
    pass compiles again inside the timing."""
    import numba

    from sparsecast import volume as volume_module
    from sparsecast.kernels.bricks import brick_minmax

    vol = Volume(np.arange(5 * 6 * 7, dtype=np.int16).reshape(5, 6, 7))
    assert numba.typeof(volume_module._tiny_voxels(vol.dtype)) == numba.typeof(vol.data)
    monkeypatch.setattr(volume_module, "_WARM_DTYPES", set())
    stats = vol.brick_stats(4)
    assert stats.compile_ms > 0
    assert numba.typeof(vol.data) in [sig[0] for sig in brick_minmax.signatures]
    again = Volume(vol.data.copy()).brick_stats(4)
    assert again.compile_ms == 0.0  # once per dtype and process
    np.testing.assert_array_equal(again.vmin, stats.vmin)
