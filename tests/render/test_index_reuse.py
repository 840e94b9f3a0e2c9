"""render() keeps the exact index it builds from a name with the volume (render/reuse.py).

A kept index must give the image a fresh one gives (equal to naive), for the frame's
own TF; it is reused only while the TF leaves the same space empty, and never for
other options, another spacing, or an approximate index.
"""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.render import same_emptiness

from synthetic import sparse_volume

ATOL = 1e-5


@pytest.fixture()
def vol():
    return sparse_volume(np.random.default_rng(5), (30, 27, 33), 6)


def _naive(vol, tf, cam, **kw):
    return sc.render(vol, tf, cam, 32, 28, index="naive", **kw)


@pytest.mark.parametrize("name", ["auto", "kdtree-deep", "grid-mm", "lbvh"])
def test_a_camera_path_builds_once(vol, name):
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.3)
    first = sc.render(vol, tf, sc.Camera.orbit(vol, 10, 5), 32, 28, index=name)
    assert not first.stats["index_reused"]
    for azimuth in (40, 130):
        cam = sc.Camera.orbit(vol, azimuth, 25)
        img = sc.render(vol, tf, cam, 32, 28, index=name)
        assert img.stats["index_reused"] and img.stats["build_ms"] == 0.0
        assert img.stats["index"] == first.stats["index"]
        assert np.abs(img.rgba - _naive(vol, tf, cam).rgba).max() <= ATOL
        assert img.stats["samples"] < _naive(vol, tf, cam).stats["samples"]  # it still skips


def test_a_colour_edit_reuses_the_index_and_shows_the_new_colours(vol):
    cam = sc.Camera.orbit(vol, 30, 20)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.3)
    other = sc.TransferFunction.preset("magma", (0.0, 1.0), threshold=0.3)
    assert same_emptiness(tf, other) and other is not tf
    sc.render(vol, tf, cam, 32, 28, index="kdtree-deep")
    img = sc.render(vol, other, cam, 32, 28, index="kdtree-deep")
    assert img.stats["index_reused"]
    ref = _naive(vol, other, cam)
    assert np.abs(img.rgba - ref.rgba).max() <= ATOL
    assert np.abs(img.rgba - _naive(vol, tf, cam).rgba).max() > 0.01  # the colours did change


def test_a_change_of_emptiness_rebuilds(vol):
    cam = sc.Camera.orbit(vol, 30, 20)
    sparse = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.6)
    dense = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    assert not same_emptiness(sparse, dense)
    sc.render(vol, sparse, cam, 32, 28, index="kdtree-deep")
    img = sc.render(vol, dense, cam, 32, 28, index="kdtree-deep")
    assert not img.stats["index_reused"]
    assert np.abs(img.rgba - _naive(vol, dense, cam).rgba).max() <= ATOL
    # and back: the sparse TF's index is kept beside the dense one's (a few per volume)
    again = sc.render(vol, sparse, cam, 32, 28, index="kdtree-deep")
    assert again.stats["index_reused"]
    assert np.abs(again.rgba - _naive(vol, sparse, cam).rgba).max() <= ATOL


def test_iso_frames_reuse_the_index_of_their_isovalue_only(vol):
    cam = sc.Camera.orbit(vol, 30, 20)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    first = sc.render(vol, tf, cam, 32, 28, index="kdtree-deep", mode="iso", iso=0.4)
    same = sc.render(vol, tf, sc.Camera.orbit(vol, 80, 10), 32, 28, index="kdtree-deep", mode="iso", iso=0.4)
    moved = sc.render(vol, tf, cam, 32, 28, index="kdtree-deep", mode="iso", iso=0.6)
    assert not first.stats["index_reused"] and same.stats["index_reused"] and not moved.stats["index_reused"]
    ref = _naive(vol, tf, cam, mode="iso", iso=0.6)
    assert np.abs(moved.rgba - ref.rgba).max() <= ATOL


def test_alternating_iso_and_dvr_frames_keep_both_indices(vol):
    """Isosurface frames classify with their own TF (non-zero only at the isovalue): its
    index and the DVR TF's are kept side by side, so toggling the mode builds nothing."""
    cam = sc.Camera.orbit(vol, 30, 20)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.3)
    modes = ({"mode": "iso", "iso": 0.4}, {})
    for kw in modes:
        assert not sc.render(vol, tf, cam, 16, 16, index="kdtree-deep", **kw).stats["index_reused"]
    for _ in range(2):
        for kw in modes:
            img = sc.render(vol, tf, cam, 16, 16, index="kdtree-deep", **kw)
            assert img.stats["index_reused"] and img.stats["build_ms"] == 0.0, kw
            assert np.abs(img.rgba - sc.render(vol, tf, cam, 16, 16, index="naive", **kw).rgba).max() <= ATOL


def test_other_options_spacing_and_approximate_indices_build_anew(vol):
    cam = sc.Camera.orbit(vol, 30, 20)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.3)
    sc.render(vol, tf, cam, 16, 16, index="grid-mm", cell=4)
    assert not sc.render(vol, tf, cam, 16, 16, index="grid-mm", cell=8).stats["index_reused"]
    assert sc.render(vol, tf, cam, 16, 16, index="grid-mm", cell=4).stats["index_reused"]
    vol.spacing = np.array([1.0, 2.0, 0.5])
    img = sc.render(vol, tf, cam, 16, 16, index="grid-mm", cell=4)
    assert not img.stats["index_reused"]
    assert np.abs(img.rgba - sc.render(vol, tf, cam, 16, 16, index="naive").rgba).max() <= ATOL
    # the BIH's single-sample mode reads the TF's values, so it is never kept
    for _ in range(2):
        approx = sc.render(vol, tf, cam, 16, 16, index="bih", mode="single-sample")
        assert not approx.stats["index_reused"] and approx.stats["build_ms"] > 0


def test_the_volume_keeps_a_few_entries():
    v = sc.Volume(np.zeros((4, 4, 4), np.float32))
    for i in range(10):
        v.keep_derived(("k", i), i, limit=3)
    assert [v.derived(("k", i)) for i in range(10)] == [None] * 7 + [7, 8, 9]
    v.keep_derived(("k", 7), "new", limit=3)  # replacing an entry makes it the newest
    v.keep_derived(("k", 10), 10, limit=3)
    assert v.derived(("k", 8)) is None and v.derived(("k", 7)) == "new"


def test_an_entry_read_outlives_newer_ones():
    """Least recently used goes first: the index a viewer reads at every frame is not
    dropped by the indices a TF drag keeps beside it."""
    v = sc.Volume(np.zeros((4, 4, 4), np.float32))
    for i in range(3):
        v.keep_derived(("k", i), i, limit=3)
    for i in range(3, 8):
        assert v.derived(("k", 0)) == 0  # read at every "frame"
        v.keep_derived(("k", i), i, limit=3)
    assert v.derived(("k", 0)) == 0
    assert [v.derived(("k", i)) for i in range(1, 8)] == [None] * 5 + [6, 7]

