"""Atlas packing: tiles never overlap and stay inside the atlas."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sparsecast.surface import build_rbvh
from sparsecast.surface.atlas import pack_tiles, tile_frames
from sparsecast.surface.mesh import icosphere


def _assert_disjoint(rect: np.ndarray, shape: tuple[int, int]) -> None:
    cover = np.zeros(shape, np.int32)
    for x0, y0, r in rect:
        assert x0 >= 0 and y0 >= 0 and x0 + r <= shape[1] and y0 + r <= shape[0]
        cover[y0:y0 + r, x0:x0 + r] += 1
    assert cover.max() <= 1, "two tiles share texels"
    assert cover.sum() == int(np.sum(rect[:, 2].astype(np.int64) ** 2))


@settings(max_examples=25)
@given(st.lists(st.integers(1, 40), min_size=1, max_size=200))
def test_shelf_packing_never_overlaps(res):
    rect, shape = pack_tiles(np.array(res))
    np.testing.assert_array_equal(rect[:, 2], res)
    _assert_disjoint(rect, shape)
    # Shelves waste little: sorted tiles fill most of the atlas.
    assert np.sum(np.square(res)) >= 0.4 * shape[0] * shape[1]


def test_built_atlas_tiles_are_disjoint():
    index = build_rbvh(icosphere(4), "Q3")
    _assert_disjoint(index.tile_rect, index.atlas_depth.shape)


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
    pos, nrm, rc = atlas_texels(index)
    inside = np.all((pos[:, :2] > 0) & (pos[:, :2] < 1), axis=1)
    np.testing.assert_allclose(pos[inside, 2], 0.0, atol=1e-6)
    np.testing.assert_allclose(np.abs(nrm[:, 2]), 1.0, atol=1e-2)
    # Store x + 2y per texel: a linear field, so bilinear reads are exact.
    layer = np.zeros(index.atlas_depth.shape)
    layer[rc[:, 0], rc[:, 1]] = pos[:, 0] + 2 * pos[:, 1]
    target = np.c_[rng.uniform(0.05, 0.95, (300, 2)), np.zeros(300)]
    hits = raycast(index, target + [0, 0, 1], np.tile([0.0, 0.0, -1.0], (300, 1)))
    got = read_layer(index, layer, hits.tile, hits.uv)
    np.testing.assert_allclose(got, target[:, 0] + 2 * target[:, 1], atol=1e-5)
    assert np.isnan(read_layer(index, layer, np.array([-1]), np.zeros((1, 2))))[0]
