"""Bricked volumes render what the dense volume renders, for every index, mode and layout.

The oracle of the project: the same global lattice, so the same floats. A bricked
volume must give the dense volume's image (<= 1e-5; in practice bit for bit) with
its bricks stored eagerly, read lazily from an array-like source, or paged under a
memory budget that forces evictions between transfer-function edits.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.index.registry import _INDICES
from synthetic import label_volume, sparse_volume

EXACT = ["naive"] + [n for n in sc.available_indices() if n != "naive" and _INDICES[n].exact
                     and not n.startswith("test-")]
ATOL = 1e-5


class ChunkedArray:
    """An array-like that is not an ndarray (as a Zarr array or HDF5 dataset is):
    shape, dtype, chunks and slicing that returns copies; counts its reads."""

    def __init__(self, a: np.ndarray, chunks=(16, 16, 16)) -> None:
        self._a = a
        self.shape = a.shape
        self.dtype = a.dtype
        self.chunks = chunks
        self.reads = 0

    def __getitem__(self, key):
        self.reads += 1
        return np.array(self._a[key])


def _same(dense, bricked, tf, cam, w=20, h=18, **kw):
    ref = sc.render(dense, tf, cam, w, h, **kw)
    img = sc.render(bricked, tf, cam, w, h, **kw)
    diff = float(np.abs(img.rgba - ref.rgba).max())
    assert diff <= ATOL, f"{kw}: bricked differs from dense by {diff:.3g}"
    return img, ref


def _cameras(vol):
    c = vol.center
    L = vol.diagonal
    lo, hi = vol.bounds
    inside = lo + (hi - lo) * np.array([0.4, 0.55, 0.5])
    return [
        sc.Camera.orbit(vol, 30, 20),
        sc.Camera.orbit(vol, -125, -35, projection="orthographic"),
        sc.Camera.look_at(c - [L, 0, 0], c, projection="orthographic", ortho_height=L),  # axis-parallel
        sc.Camera.look_at(c + [L, 0.0, 0.5 * (hi[2] - lo[2]) - 1e-9], c + [0, 0, 0.5 * (hi[2] - lo[2]) - 1e-9],
                          projection="orthographic", ortho_height=L),  # grazing a face
        sc.Camera.look_at(inside, inside + [0.3, 1.0, -0.2], fov_y=100),  # inside the volume
    ]


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(3)
    vol = sparse_volume(rng, (37, 29, 45), 7, spacing=(1.0, 0.8, 1.3), origin=(2.0, -1.0, 0.5))
    return vol


@pytest.mark.parametrize("index", EXACT)
@pytest.mark.parametrize("layout", ["eager", "lazy", "lazy16"])
def test_every_index_equals_dense(scene, index, layout):
    a = scene.data
    kw = dict(spacing=scene.spacing, origin=scene.origin)
    bricked = {
        "eager": lambda: sc.BrickedVolume(a, **kw),
        "lazy": lambda: sc.BrickedVolume(ChunkedArray(a), **kw),
        "lazy16": lambda: sc.BrickedVolume(ChunkedArray(a, (8, 40, 13)), brick_size=16, **kw),
    }[layout]()
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.15)
    for cam in _cameras(scene):
        _same(scene, bricked, tf, cam, index=index, dt=0.45, ert=1.0)
        _same(scene, bricked, tf, cam, index=index, dt=0.7, shading=True)
    img, ref = _same(scene, bricked, tf, _cameras(scene)[0], index=index, ert=1.0)
    assert img.stats["samples"] == ref.stats["samples"]


# Traversal on bricks is covered for every index by the DVR test above; the iso modes
# only change the sampling side, so two indices keep the (cold) compile count down.
@pytest.mark.parametrize("index", ["naive", "kdtree-deep"])
@pytest.mark.parametrize("mode", ["iso", "iso+dvr"])
def test_iso_modes_equal_dense(scene, index, mode):
    bricked = sc.BrickedVolume(ChunkedArray(scene.data), spacing=scene.spacing, origin=scene.origin)
    tf = sc.TransferFunction.preset("magma", (0.0, 1.0), threshold=0.4)
    for cam in _cameras(scene)[:3]:
        _same(scene, bricked, tf, cam, index=index, mode=mode, iso=[0.3, 0.6])


def test_gradients_across_brick_faces():
    """A ramp whose cells straddle brick faces on all three axes, shaded: each sample's
    gradient reads its neighbours from the apron of its own brick."""
    n = 33
    z, y, x = np.meshgrid(*(np.arange(n),) * 3, indexing="ij")
    a = (((x - 16.0) ** 2 + (y - 15.5) ** 2 + (z - 16.3) ** 2) < 100).astype(np.float32) * (x + 2 * y + 3 * z) / 200
    dense = sc.Volume(a)
    bricked = sc.BrickedVolume(ChunkedArray(a, (9, 9, 9)))
    tf = sc.TransferFunction([(0.0, 0, 0, 0, 0), (0.05, 1, 0.5, 0, 0.5), (1.0, 1, 1, 1, 1)])
    for cam in _cameras(dense):
        _same(dense, bricked, tf, cam, index="naive", shading=True, dt=0.37)


def test_background_bricks_at_faces_and_corners():
    """Non-zero background, data only in corner and face bricks; absent bricks read
    the background exactly, so a TF that shows the background still matches."""
    a = np.full((30, 26, 35), 5, np.uint16)
    a[:4, :4, :4] = 900  # a corner brick
    a[-3:, 10:14, -2:] = 400  # at the far faces
    a[12:18, -1:, 15:20] = 650
    dense = sc.Volume(a)
    bricked = sc.BrickedVolume(ChunkedArray(a), background=5)
    assert bricked.stored_bricks < np.prod(bricked.brick_grid)
    for tf in (sc.TransferFunction.preset("hot", (0, 1000), threshold=0.2),
               sc.TransferFunction([(0, 1, 1, 1, 0.05), (1000, 1, 0, 0, 0.9)])):  # background visible
        for cam in _cameras(dense):
            for index in ("naive", "kdtree-deep"):
                _same(dense, bricked, tf, cam, index=index, ert=1.0)


@pytest.mark.parametrize("smooth", [False, True])
def test_labels_sample_nearest_on_bricks(rng, smooth):
    """Nearest and smooth label sampling (the eight corners from one slot, a normal's
    neighbours from their own bricks) read bricks as they read the dense array."""
    vol = label_volume(rng, (30, 34, 27), 5, brick_aligned=True)
    bricked = sc.BrickedVolume(vol.data)
    tf = sc.TransferFunction.labels({1: (1, 0, 0, 1), 3: (0, 1, 0, 0.5), 5: (0, 0, 1, 0.7)}, smooth=smooth)
    for cam in _cameras(vol)[:3]:
        for index in ("naive", "grid-pc", "kdtree-deep", "bih"):
            _same(vol, bricked, tf, cam, index=index)
        _same(vol, bricked, tf, cam, index="kdtree-deep", shading=True, clip_cap=True,
              clip_planes=[((13.0, 16.0, 14.0), (0.4, -1.0, 0.2))])
    assert bricked.label_counts()[0].tolist() == vol.label_counts()[0].tolist()


def _two_blobs():
    """Two blobs far apart with disjoint value ranges: a TF sees one or the other."""
    a = np.zeros((40, 40, 72), np.float32)
    a[4:20, 5:21, 3:30] = np.linspace(0.2, 0.4, 27, dtype=np.float32)
    a[20:36, 18:34, 40:70] = np.linspace(0.6, 0.9, 30, dtype=np.float32)
    return a


def test_memory_budget_pages_bricks_between_tf_edits():
    a = _two_blobs()
    dense = sc.Volume(a)
    src = ChunkedArray(a)
    brick_bytes = 11 ** 3 * 4
    low = sc.TransferFunction([(0.0, 0, 0, 0, 0), (0.19, 0, 0, 0, 0), (0.2, 1, 0, 0, 0.6), (0.45, 1, 1, 0, 0.6),
                               (0.5, 0, 0, 0, 0), (1.0, 0, 0, 0, 0)])
    high = sc.TransferFunction([(0.0, 0, 0, 0, 0), (0.55, 0, 0, 0, 0), (0.6, 0, 0, 1, 0.6), (1.0, 0, 1, 1, 0.6)])
    n_low = int(np.count_nonzero(low.classify_bricks(dense, 8)))
    n_high = int(np.count_nonzero(high.classify_bricks(dense, 8)))
    limit = max(n_low, n_high) * brick_bytes  # one blob at a time, not both
    assert limit < (n_low + n_high) * brick_bytes
    bricked = sc.BrickedVolume(src, memory_limit=limit)
    cam = sc.Camera.orbit(dense, 20, 30)
    loaded = []
    for tf in (low, high, low, high):
        for index in ("naive", "kdtree-deep"):
            _same(dense, bricked, tf, cam, 24, 24, index=index, shading=True)
        loaded.append(bricked.loads["bricks"])
        assert bricked._pool.nbytes <= limit
    # Each edit had to load the other blob again: evictions happened.
    assert loaded[0] < loaded[1] < loaded[2] < loaded[3]
    both = sc.TransferFunction([(0.0, 0, 0, 0, 0), (0.15, 0, 0, 0, 0), (0.2, 1, 1, 1, 0.5), (1.0, 1, 1, 1, 0.5)])
    with pytest.raises(sc.MemoryBudgetError, match=r"needs \d+ bricks .* MiB.*memory_limit"):
        sc.render(bricked, both, cam, 8, 8)
    sc.render(bricked, low, cam, 8, 8)  # and it recovers


def test_statistics_and_round_trip(scene):
    a = scene.data
    for src in (a, ChunkedArray(a, (5, 7, 11))):
        for B in (8, 16):
            bricked = sc.BrickedVolume(src, brick_size=B)
            for b in sorted({B, 2 * B, 32, 4 if B == 8 else 8}):
                if B == 16 and b == 4:
                    continue
                got = bricked.brick_stats(b)
                want = scene.brick_stats(b)
                if bricked.resident_bricks == bricked.stored_bricks or b % B == 0:
                    assert np.array_equal(got.vmin, want.vmin) and np.array_equal(got.vmax, want.vmax), (B, b)
                else:  # divisors of B from bricks not resident: a superset of the range
                    assert np.all(got.vmin <= want.vmin) and np.all(got.vmax >= want.vmax)
            assert bricked.value_range == scene.value_range
            assert np.array_equal(bricked.to_dense(), a)


def test_sparse_storage_is_small_and_reads_only_needed_bricks():
    a = np.zeros((64, 64, 64), np.uint8)
    a[8:16, 8:16, 8:16] = 200
    src = ChunkedArray(a, (16, 16, 16))
    bricked = sc.BrickedVolume(src, memory_limit="10MB")
    assert bricked.stored_bricks == 27  # the cube's brick and its neighbours through the apron
    assert bricked.resident_bricks == 0  # nothing read before a TF asks
    tf = sc.TransferFunction.preset("gray", (0, 255), threshold=0.5)
    sc.render(bricked, tf, sc.Camera.orbit(bricked), 8, 8, index="kdtree-deep")
    assert 0 < bricked.resident_bricks <= 27
    assert bricked.nbytes < a.nbytes


def test_bad_input():
    with pytest.raises(sc.ParameterError, match="brick_size"):
        sc.BrickedVolume(np.zeros((9, 9, 9), np.uint8), brick_size=12)
    with pytest.raises(sc.ParameterError, match="memory_limit"):
        sc.BrickedVolume(np.zeros((9, 9, 9), np.uint8), memory_limit="lots")
    with pytest.raises(sc.VolumeDataError, match="3-D"):
        sc.BrickedVolume(np.zeros((9, 9), np.uint8))
    bad = np.zeros((12, 12, 12), np.float32)
    bad[3, 4, 5] = np.nan
    with pytest.raises(sc.VolumeDataError, match="NaN"):
        sc.BrickedVolume(ChunkedArray(bad))
    with pytest.raises(sc.VolumeDataError, match="to_dense"):
        sc.BrickedVolume(np.zeros((9, 9, 9), np.uint8)).data

    class Broken(ChunkedArray):
        def __getitem__(self, key):
            raise OSError("chunk 0.0.1 is corrupt")

    with pytest.raises(sc.VolumeDataError, match="chunk 0.0.1 is corrupt"):
        sc.BrickedVolume(Broken(np.zeros((9, 9, 9), np.uint8)))


@st.composite
def bricked_scenes(draw):
    shape = tuple(draw(st.integers(2, 36)) for _ in range(3))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    vol = sparse_volume(rng, shape, draw(st.integers(0, 5)),
                        spacing=tuple(draw(st.sampled_from([0.6, 1.0, 1.7])) for _ in range(3)))
    xs = sorted(draw(st.lists(st.integers(-10, 110).map(lambda i: i / 100), min_size=2, max_size=4)))
    if xs[-1] == xs[0]:
        xs[-1] += 0.01
    tf = sc.TransferFunction([(x, draw(st.floats(0, 1)), 0.5, 0.5, draw(st.sampled_from([0.0, 0.3, 1.0])))
                              for x in xs])
    if draw(st.booleans()):
        cam = sc.Camera.orbit(vol, draw(st.sampled_from([0.0, 90.0, 33.0, -71.0])),
                              draw(st.sampled_from([0.0, 90.0, 12.0, -47.0])),
                              projection=draw(st.sampled_from(["orthographic", "perspective"])))
    else:
        lo, hi = vol.bounds
        eye = lo + (hi - lo) * np.array([draw(st.floats(-0.5, 1.5)) for _ in range(3)])
        cam = sc.Camera.look_at(eye, vol.center + 0.01, fov_y=80.0)
    return vol, tf, cam, draw(st.sampled_from([8, 16])), draw(st.sampled_from([0.3, 0.77])), draw(st.booleans())


@settings(max_examples=20, deadline=None)
@given(data=bricked_scenes(), index=st.sampled_from(EXACT))
def test_property_bricked_equals_dense(data, index):
    vol, tf, cam, B, dt, shading = data
    bricked = sc.BrickedVolume(ChunkedArray(vol.data, (7, 16, 9)), vol.spacing, brick_size=B)
    _same(vol, bricked, tf, cam, 12, 10, index=index, dt=dt, shading=shading)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_read_window_equals_the_dense_window_from_bricks_or_from_the_source(seed, lazy):
    rng = np.random.default_rng(seed)
    shape = tuple(int(n) for n in rng.integers(9, 30, 3))
    a = (rng.random(shape) * (rng.random(shape) < 0.3)).astype(np.float32)
    vol = sc.BrickedVolume(a, eager=not lazy)  # eager: the pool alone; lazy: the source
    lo = [int(rng.integers(-2, n)) for n in shape]
    hi = [int(rng.integers(l, n + 3)) for l, n in zip(lo, shape)]
    got = vol.read_window(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])
    # clipped to the volume; an upper bound <= 0 is an empty window (not numpy's from-the-end)
    c = [slice(max(l, 0), max(min(h, n), 0)) for l, h, n in zip(lo, hi, shape)]
    np.testing.assert_array_equal(got, a[tuple(c)])
    np.testing.assert_array_equal(vol.to_dense(), a)
