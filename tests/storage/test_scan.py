"""The chunk-parallel scan (:func:`sparsecast.storage.scan`) against the dense Volume, bit for bit."""

from __future__ import annotations

from types import SimpleNamespace

import dask.array as da
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.errors import FileFormatError, VolumeDataError
from sparsecast.io import convert_volume, open_source
from sparsecast.storage import scan
from sparsecast.storage.scan import scan_blocks


def _sparse(shape, dtype, seed) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a = rng.random(shape) * 300 - (50 if np.dtype(dtype).kind in "if" else 0)
    a[rng.random(shape) < 0.6] = 0
    if np.dtype(dtype).kind == "u":
        a = np.clip(a, 0, np.iinfo(dtype).max)
    return a.astype(dtype)


def _assert_same_as_dense(s, a, brick_size, nonfinite="raise"):
    dense = sc.Volume(a, nonfinite=nonfinite)
    ref = dense.brick_stats(brick_size)
    assert s.vmin.shape == ref.vmin.shape
    # Bit for bit: the same float64 values (assert_array_equal treats -0.0 == 0.0).
    np.testing.assert_array_equal(s.vmin, ref.vmin)
    np.testing.assert_array_equal(s.vmax, ref.vmax)
    assert s.value_range == dense.value_range
    counts, edges = np.histogram(dense.data, 256, range=dense.value_range)
    np.testing.assert_array_equal(s.counts, counts)
    np.testing.assert_array_equal(s.edges, edges)
    assert s.edges.dtype == edges.dtype


@settings(max_examples=40, deadline=None)
@given(
    shape=st.tuples(*[st.integers(1, 19)] * 3),
    chunks=st.tuples(*[st.integers(1, 11)] * 3),
    brick_size=st.integers(1, 9),
    dtype=st.sampled_from(["uint8", "uint16", "int16", "float32", "float64"]),
    seed=st.integers(0, 2**16),
)
def test_scan_equals_dense_brick_stats_for_any_chunking(shape, chunks, brick_size, dtype, seed):
    a = _sparse(shape, dtype, seed)
    s = scan(da.from_array(a, chunks=chunks), brick_size)
    _assert_same_as_dense(s, a, brick_size)
    assert s.nonfinite == 0


@pytest.mark.parametrize("brick_size", [4, 8, 16])
@pytest.mark.parametrize("dtype", ["uint8", "float32"])
def test_scan_of_a_zarr_source_with_unaligned_chunks(tmp_path, brick_size, dtype):
    a = _sparse((37, 50, 23), dtype, 7)
    store = convert_volume(a, tmp_path / "s.zarr", chunks=(5, 13, 7)).path
    src = open_source(store)
    s = scan(src, brick_size)
    _assert_same_as_dense(s, a, brick_size)
    # the blocks are whole store chunks: every block boundary is a chunk boundary
    for axis, sizes in enumerate(s.blocks):
        starts = np.cumsum((0,) + sizes[:-1])
        assert (starts % src.chunks[axis] == 0).all()


def test_scan_blocks_grow_whole_chunks_up_to_the_target():
    assert scan_blocks((100, 100, 100), 1, (10, 10, 10), target=10 * 100 * 100) == (10, 100, 100)
    assert scan_blocks((100, 100, 100), 4, None, target=4 * 3 * 100 * 100) == (3, 100, 100)
    assert scan_blocks((64, 4096, 4096), 1, None, target=4 << 20) == (16, 64, 4096)  # planes of 256 KiB
    assert scan_blocks((5, 5, 5), 1, (64, 64, 64)) == (5, 5, 5)


def _with_nonfinite(seed=3):
    a = _sparse((21, 17, 30), "float32", seed)
    a[0, 0, 0] = np.nan          # a corner
    a[20, 16, 29] = -np.inf      # the opposite corner
    a[10, 8, 15] = np.inf
    a[10, 9, 15] = np.nan
    a[:, :, 4:6][a[:, :, 4:6] > 200] = np.nan  # a few more inside bricks
    return a


def test_nonfinite_raise_names_the_count():
    a = _with_nonfinite()
    n = int((~np.isfinite(a)).sum())
    with pytest.raises(VolumeDataError, match=rf"{n} voxel\(s\) are NaN or Inf"):
        scan(da.from_array(a, chunks=(4, 5, 6)))


@pytest.mark.parametrize("chunks", [(4, 5, 6), (21, 17, 30), (1, 17, 7)])
@pytest.mark.parametrize("brick_size", [2, 8])
def test_nonfinite_replace_equals_the_dense_policy(chunks, brick_size):
    a = _with_nonfinite()
    s = scan(da.from_array(a, chunks=chunks), brick_size, nonfinite="replace")
    assert (s.nan, s.posinf, s.neginf) == (int(np.isnan(a).sum()), int(np.isposinf(a).sum()),
                                           int(np.isneginf(a).sum()))
    _assert_same_as_dense(s, a, brick_size, nonfinite="replace")


def test_only_nonfinite_voxels_raise():
    with pytest.raises(VolumeDataError, match="every voxel is NaN or Inf"):
        scan(np.full((3, 4, 5), np.nan, np.float32), nonfinite="replace")


def test_progress_callback_counts_every_block():
    seen = []
    a = _sparse((20, 20, 20), "uint8", 1)
    s = scan(da.from_array(a, chunks=(5, 20, 10)), progress=lambda done, total: seen.append((done, total)))
    assert sorted(seen) == [(i, 8) for i in range(1, 9)]
    assert s.blocks == ((5, 5, 5, 5), (20,), (10, 10))


def test_no_histogram_when_bins_is_zero():
    s = scan(_sparse((9, 9, 9), "float32", 2), bins=0)
    assert s.counts is None and s.edges is None


def test_brick_stats_of_a_scan_serve_as_the_volumes(tmp_path):
    a = _sparse((30, 20, 10), "uint16", 4)
    stats = scan(a, 8).brick_stats()
    assert stats.brick_size == 8 and stats.shape == sc.Volume(a).brick_stats(8).shape


def test_scan_stops_at_a_missing_chunk_naming_it(tmp_path):
    a = _sparse((40, 40, 40), "uint8", 5)
    store = convert_volume(a, tmp_path / "m.zarr", chunks=16).path
    (store / "c" / "2" / "0" / "1").unlink()
    with pytest.raises(FileFormatError, match=r"chunk 'c/2/0/1'.*missing") as exc:
        scan(open_source(store))
    assert str(store) in str(exc.value)


def test_bad_input():
    with pytest.raises(VolumeDataError, match="3-D"):
        scan(np.zeros((4, 4)))
    with pytest.raises(VolumeDataError, match="real number"):
        scan(np.zeros((2, 2, 2), complex))


@pytest.mark.parametrize("array", [np.zeros((4, 5), np.uint8), np.zeros((3, 0, 5), np.uint8),
                                   np.full((3, 4, 5), np.nan, np.float32)], ids=["2-D", "zero axis", "all NaN"])
def test_every_volume_kind_words_a_bad_array_alike(array):
    """A volume in memory, a bricked one and a chunked scan reject the same array with the
    same message (one wording, kept in ``sparsecast.volume``), naming the volume."""
    messages = set()
    for make in (lambda: sc.Volume(array, name="v.npy"),
                 lambda: sc.BrickedVolume(array, name="v.npy"),
                 lambda: scan(SimpleNamespace(array=array, path="v.npy"))):  # as a Source names its file
        with pytest.raises(VolumeDataError) as err:
            make()
        messages.add(str(err.value))
    assert len(messages) == 1
    assert next(iter(messages)).startswith("'v.npy': ")
