"""The texel pool: tiles never overlap, fill the pool, and their records are cache lines."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sparsecast.errors import ParameterError
from sparsecast.surface import build_rbvh
from sparsecast.surface.atlas import pool_offsets, tile_frames, tile_records
from sparsecast.surface.mesh import icosphere


def _assert_tiled(offset: np.ndarray, res: np.ndarray, n: int) -> None:
    """Tile runs ``offset[k] .. offset[k] + res[k]**2`` cover ``0 .. n`` once each."""
    cover = np.zeros(n, np.int32)
    for o, r in zip(offset.tolist(), res.tolist()):
        assert o >= 0 and o + r * r <= n
        cover[o:o + r * r] += 1
    assert cover.min() == 1 and cover.max() == 1, "a texel in no tile or in two"


@settings(max_examples=25)
@given(st.lists(st.integers(1, 40), min_size=1, max_size=200))
def test_pool_offsets_lay_tiles_end_to_end(res):
    offset, n = pool_offsets(np.array(res))
    assert n == int(np.sum(np.square(res)))
    _assert_tiled(offset, np.array(res), n)


def test_pool_past_int32_offsets_is_one_clear_error():
    with pytest.raises(ParameterError, match="2\\*\\*31"):
        pool_offsets(np.array([46341, 2]))  # 46341**2 > 2**31


def test_tile_records_are_cache_lines_with_their_fields(rng):
    proj = rng.normal(size=(5, 12)).astype(np.float32)
    height = rng.normal(size=(5, 2)).astype(np.float32)
    offset, res = np.array([0, 36, 100, 164, 200]), np.array([6, 8, 8, 6, 4])
    rec = tile_records(proj, height, offset, res)
    assert rec.shape == (5, 16) and rec.dtype == np.float32 and rec.ctypes.data % 64 == 0
    np.testing.assert_array_equal(rec[:, :12], proj)
    np.testing.assert_array_equal(rec[:, 12:14], height)
    np.testing.assert_array_equal(rec.view(np.int32)[:, 14], offset)
    np.testing.assert_array_equal(rec.view(np.int32)[:, 15], res)


def test_built_atlas_tiles_are_disjoint():
    index = build_rbvh(icosphere(4), "Q3", mip_levels=2)
    assert index.atlas_depth.ndim == 1 and index.atlas_normal.shape == (len(index.atlas_depth), 3)
    _assert_tiled(index.tile_offset, index.tile_res, len(index.atlas_depth))
    assert index.tiles.ctypes.data % 64 == 0


def test_tile_frames_are_orthonormal_and_follow_the_normal(rng):
    n = rng.normal(size=(100, 3))
    n[0] = (0.0, 0.0, 1.0)
    f = tile_frames(n)
    np.testing.assert_allclose(np.einsum("tij,tkj->tik", f, f), np.broadcast_to(np.eye(3), (100, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(f[:, 2], n / np.linalg.norm(n, axis=1, keepdims=True))
    np.testing.assert_allclose(np.linalg.det(f), 1.0)  # right-handed


def test_atlas_as_surface_storage_round_trip(rng):
    """Texels lie on the surface, and a layer written per texel reads back at hits."""
    from sparsecast.surface import raycast
    from sparsecast.surface.atlas import atlas_texels, read_layer
    from sparsecast.surface.mesh import grid_plane

    index = build_rbvh(grid_plane(32), "Q3")
    pos, nrm, texel = atlas_texels(index)
    inside = np.all((pos[:, :2] > 0) & (pos[:, :2] < 1), axis=1)
    np.testing.assert_allclose(pos[inside, 2], 0.0, atol=1e-6)
    np.testing.assert_allclose(np.abs(nrm[:, 2]), 1.0, atol=1e-2)
    # Store x + 2y per texel: a linear field, so bilinear reads are exact.
    layer = np.zeros(index.atlas_depth.shape)
    layer[texel] = pos[:, 0] + 2 * pos[:, 1]
    target = np.c_[rng.uniform(0.05, 0.95, (300, 2)), np.zeros(300)]
    hits = raycast(index, target + [0, 0, 1], np.tile([0.0, 0.0, -1.0], (300, 1)))
    got = read_layer(index, layer, hits.tile, hits.uv)
    np.testing.assert_allclose(got, target[:, 0] + 2 * target[:, 1], atol=1e-5)
    assert np.isnan(read_layer(index, layer, np.array([-1]), np.zeros((1, 2))))[0]
