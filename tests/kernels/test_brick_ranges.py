"""The threaded brick pass (:func:`sparsecast.kernels.bricks.brick_ranges`, what
``Volume.brick_stats`` runs) equals the float64 kernel :func:`brick_minmax` bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparsecast.kernels import bricks
from sparsecast.kernels.bricks import brick_minmax, brick_ranges, brick_windows

DTYPES = ["uint8", "uint16", "int16", "float32", "float64"]


def _both(data, brick_size, workers):
    nb = tuple(len(brick_windows(n, brick_size)[0]) for n in data.shape)
    old = np.empty(nb), np.empty(nb)
    new = np.full(nb, np.nan), np.full(nb, np.nan)
    brick_minmax(data, brick_size, *nb, *old)
    brick_ranges(data, brick_size, *new, workers=workers)
    return old, new


def _bits(a):
    return (a + 0.0).view(np.uint64)  # + 0.0: -0.0 and 0.0 are one value to min/max


@settings(max_examples=60, deadline=None)
@given(
    shape=st.tuples(st.integers(1, 40), st.integers(1, 40), st.integers(1, 40)),
    brick_size=st.integers(1, 17),
    dtype=st.sampled_from(DTYPES),
    workers=st.integers(1, 3),
    task_bytes=st.sampled_from([1, 200, 4096]),
    seed=st.integers(0, 2**16),
)
def test_threaded_pass_equals_the_float64_kernel_bit_for_bit(shape, brick_size, dtype, workers, task_bytes, seed):
    rng = np.random.default_rng(seed)
    info = np.iinfo(dtype) if np.dtype(dtype).kind in "ui" else None
    if info is not None:
        data = rng.integers(info.min, info.max, shape, endpoint=True, dtype=dtype)
    else:
        data = (rng.standard_normal(shape) * 10.0 ** rng.integers(-3, 30)).astype(dtype)
    data[rng.random(shape) < 0.5] = 0  # sparse: runs of equal values, bricks of one value
    data.setflags(write=False)
    # Tiny tasks: many slabs (of one brick row and its apron planes) on several threads.
    old_task = bricks.TASK_BYTES
    bricks.TASK_BYTES = task_bytes
    try:
        (omin, omax), (nmin, nmax) = _both(data, brick_size, workers)
    finally:
        bricks.TASK_BYTES = old_task
    np.testing.assert_array_equal(_bits(nmin), _bits(omin))
    np.testing.assert_array_equal(_bits(nmax), _bits(omax))


@pytest.mark.parametrize("dtype", DTYPES)
def test_threaded_pass_of_a_volume_larger_than_two_tasks(dtype):
    """The default task size on a volume of several tasks."""
    rng = np.random.default_rng(1)
    data = (rng.random((40, 300, 520)) * 200).astype(dtype)
    assert data.nbytes > 2 * bricks.TASK_BYTES or dtype == "uint8"
    (omin, omax), (nmin, nmax) = _both(data, 8, 2)
    np.testing.assert_array_equal(nmin, omin)
    np.testing.assert_array_equal(nmax, omax)


def test_windows_cover_every_voxel_with_the_apron():
    lo, hi = brick_windows(17, 8)
    assert lo.tolist() == [0, 7] and hi.tolist() == [9, 16]
    assert brick_windows(1, 8)[0].tolist() == [0] and brick_windows(1, 8)[1].tolist() == [0]
