"""RBVH accuracy on analytic shapes, seams without cracks, hybrid leaves, presets, errors.

Stated error: an RBVH hit lies within ``TEXELS`` texels of the surface, plus the
mesh's own deviation from the analytic shape. A nominal texel is
``sqrt(area / rho)`` (the quality's pixel-to-area ratio on the mesh normalised to
area 1); at creases the bound is the largest texel spacing of any tile.
"""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast.errors import ParameterError
from sparsecast.surface import QUALITY, PointCloud, build_bvh, build_rbvh, raycast
from sparsecast.surface.mesh import TriangleMesh, box_mesh, grid_plane, icosphere

from .brute import brute_force_hits, rays_at

TEXELS = 1.5


def texel(mesh, quality: str) -> float:
    return float(np.sqrt(mesh.area / QUALITY[quality].rho))


def max_step(index) -> float:
    """The largest texel spacing of any tile (tiles are square, their rectangles need not be)."""
    inv = np.linalg.norm(index.tile_proj[:, 3:9].reshape(-1, 2, 3).astype(np.float64), axis=2)
    return float(1.0 / inv.min())


def _dirs_from_above(rng, n, min_elevation_deg=20.0):
    el = np.radians(rng.uniform(min_elevation_deg, 90.0, n))
    az = rng.uniform(0, 2 * np.pi, n)
    return -np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)


@pytest.mark.parametrize("quality", ["Q0", "Q2", "Q4"])
def test_plane_hits_are_on_the_plane(rng, quality):
    mesh = grid_plane(64)
    index = build_rbvh(mesh, quality)
    s = index.stats()
    assert s["tiles"] > 1 and s["triangles"] == 0  # a plane is all height field
    n = 1500
    target = np.c_[rng.uniform(0.01, 0.99, (n, 2)), np.zeros(n)]
    d = _dirs_from_above(rng, n)
    hits = raycast(index, target - 2.0 * d, d)
    assert hits.hit.all()
    np.testing.assert_allclose(hits.points[:, 2], 0.0, atol=1e-5)
    np.testing.assert_allclose(hits.points[:, :2], target[:, :2], atol=1e-4)
    np.testing.assert_allclose(np.abs(hits.normals[:, 2]), 1.0, atol=1e-2)
    assert (hits.tile >= 0).all() and (hits.face == -1).all()


@pytest.mark.parametrize("quality", ["Q1", "Q2", "Q3"])
def test_sphere_hits_within_stated_error(rng, quality):
    mesh = icosphere(5)
    index = build_rbvh(mesh, quality)
    # Rays aimed at the centre cross the surface head-on: every one must hit.
    d = rng.normal(size=(3000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = raycast(index, -3.0 * d, d)
    assert hits.hit.all()
    sagitta = 1.0 - np.linalg.norm(mesh.triangles.mean(axis=1), axis=1).min()
    err = np.abs(np.linalg.norm(hits.points, axis=1) - 1.0)
    assert err.max() <= TEXELS * texel(mesh, quality) + sagitta
    # Normals point along the radius.
    cos = np.abs(np.sum(hits.normals * hits.points, axis=1)) / np.linalg.norm(hits.points, axis=1)
    assert np.percentile(cos, 1) > 0.99
    # Against the exact BVH on arbitrary rays: grazing rays may differ at the silhouette only.
    o, d = rays_at(mesh.vertices[rng.integers(0, len(mesh.vertices), 3000)], rng, 3.0, jitter=0.2)
    exact = raycast(build_bvh(mesh), o, d)
    approx = raycast(index, o, d)
    assert (exact.hit != approx.hit).mean() < 0.01
    both = exact.hit & approx.hit
    assert np.median(np.abs(exact.t[both] - approx.t[both])) < texel(mesh, quality)


@pytest.mark.parametrize("quality", ["Q2", "Q4"])
def test_cube_hits_within_stated_error(rng, quality):
    mesh = box_mesh(n=16)
    index = build_rbvh(mesh, quality)
    n = 3000
    target = rng.uniform(0, 1, (n, 3))
    target[np.arange(n), rng.integers(0, 3, n)] = rng.integers(0, 2, n)
    o, d = rays_at(target, rng, 3.0)
    hits = raycast(index, o, d)
    p = hits.points[hits.hit]
    outside = np.linalg.norm(np.maximum(np.maximum(-p, p - 1.0), 0.0), axis=1)
    inside = np.minimum(np.abs(p), np.abs(p - 1.0)).min(axis=1)
    dist = np.where(outside > 0, outside, inside)
    # Creases: a tile's extrapolated rim may stand out by under one of its texels.
    assert dist.max() <= TEXELS * max_step(index)
    assert (dist <= 1e-6).mean() > 0.95  # flat faces are exact away from the creases
    assert hits.hit.mean() > 0.99


def test_no_cracks_at_tile_seams(rng):
    """Rays aimed at edges shared by triangles of different tiles, and at the
    vertices where tiles meet, all hit, at the exact distance up to a texel."""
    mesh = icosphere(5)
    index = build_rbvh(mesh, "Q2")
    centroids = mesh.triangles.mean(axis=1)
    # The tile each triangle is drawn in: hit its centroid head-on.
    tile_of = raycast(index, 2.0 * centroids, -centroids).tile
    edges = np.concatenate([mesh.faces[:, [0, 1]], mesh.faces[:, [1, 2]], mesh.faces[:, [2, 0]]])
    owner = np.tile(np.arange(mesh.n_triangles), 3)
    key = np.sort(edges, axis=1)
    order = np.lexsort((key[:, 1], key[:, 0]))
    k, f = key[order], owner[order]
    pair = np.all(k[1:] == k[:-1], axis=1)
    seam = pair & (tile_of[f[1:]] != tile_of[f[:-1]])
    seam_edges = k[1:][seam]
    assert len(seam_edges) > 100
    t = rng.uniform(0.0, 1.0, (len(seam_edges), 1))
    pts = (1 - t) * mesh.vertices[seam_edges[:, 0]] + t * mesh.vertices[seam_edges[:, 1]]
    pts = np.concatenate([pts, mesh.vertices[np.unique(seam_edges)]])
    o, d = rays_at(pts, rng, 3.0)
    d_in = np.sum(d * pts, axis=1) < -0.3  # from the outside, not grazing
    o, d, pts = o[d_in], d[d_in], pts[d_in]
    hits = raycast(index, o, d)
    assert hits.hit.all(), f"{(~hits.hit).sum()} of {len(o)} seam rays slipped through"
    # The targets lie on the mesh 3 units from the origins. (A brute-force
    # triangle test is no oracle here: aimed exactly at an edge, rounding can
    # reject both triangles.)
    err = np.abs(hits.t - 3.0)
    assert err.max() < TEXELS * max_step(index), f"{(err > 0.01).sum()} seam rays hit another surface"


def test_hybrid_triangle_leaves_are_exact(rng):
    # A coarse cube: nodes of fewer than 8 triangles cannot be height fields here,
    # so the hybrid keeps them as exact triangles.
    mesh = box_mesh(n=2)
    index = build_rbvh(mesh, "Q2")
    s = index.stats()
    assert s["triangle_leaves"] > 0 and s["triangles"] == mesh.n_triangles
    o, d = rays_at(rng.uniform(0, 1, (500, 3)), rng, 3.0, jitter=0.3)
    hits = raycast(index, o, d)
    t_ref, _ = brute_force_hits(mesh.triangles, o, d)
    np.testing.assert_array_equal(hits.hit, np.isfinite(t_ref))
    np.testing.assert_allclose(hits.t[hits.hit], t_ref[hits.hit], atol=1e-6)
    assert (hits.face[hits.hit] >= 0).all()


def test_mixed_mesh_uses_both_leaf_kinds(rng):
    # A fine plane (height field) plus a coarse tetrahedron (triangle leaves).
    plane = grid_plane(48)
    tet_v = np.array([[0.4, 0.4, 0.3], [0.6, 0.4, 0.3], [0.5, 0.6, 0.3], [0.5, 0.47, 0.5]])
    tet_f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]]) + len(plane.vertices)
    mesh = TriangleMesh(np.concatenate([plane.vertices, tet_v]), np.concatenate([plane.faces, tet_f]), "mix")
    index = build_rbvh(mesh, "Q3")
    s = index.stats()
    assert s["tiles"] > 0 and s["triangle_leaves"] > 0
    o = np.array([[0.5, 0.47, 2.0], [0.1, 0.1, 2.0]])
    hits = raycast(index, o, [[0, 0, -1], [0, 0, -1]])
    np.testing.assert_allclose(hits.t, [1.5, 2.0], atol=1e-5)
    assert hits.face[0] >= 0 and hits.tile[1] >= 0


def test_quality_presets_order_texels_and_median_split():
    mesh = icosphere(5)
    texels = [build_rbvh(mesh, q).stats()["texels"] for q in ("Q0", "Q2", "Q4")]
    assert texels[0] > texels[1] > texels[2]
    # rho texels per unit of normalised area, give or take borders and shelf rounding
    assert 0.5 * QUALITY["Q2"].rho < texels[1] < 4 * QUALITY["Q2"].rho
    med = build_rbvh(mesh, "Q2", split="median")
    assert med.stats()["split"] == "median" and med.n_tiles > 0


def test_overlap_band_duplicates_and_still_hits(rng):
    mesh = icosphere(4)
    plain, dup = build_rbvh(mesh, "Q2"), build_rbvh(mesh, "Q2", overlap=0.05)
    assert sum(dup.stats()["refs_per_level"]) > sum(plain.stats()["refs_per_level"])
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert raycast(dup, -3.0 * d, d).hit.all()


def test_point_cloud_discs_form_a_surface(rng):
    g = (np.arange(60) + 0.5) / 60
    xx, yy = np.meshgrid(g, g)
    pts = np.c_[xx.ravel(), yy.ravel(), np.zeros(xx.size)]
    cloud = PointCloud(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), radii=1.0 / 60)
    index = build_rbvh(cloud, "Q3")
    assert index.stats()["tiles"] > 0 and index.stats()["triangles"] == 0
    target = np.c_[rng.uniform(0.05, 0.95, (500, 2)), np.zeros(500)]
    d = _dirs_from_above(rng, 500, 30.0)
    hits = raycast(index, target - d, d)
    assert hits.hit.all()
    np.testing.assert_allclose(hits.points[:, 2], 0.0, atol=1e-5)


def test_bad_parameters():
    mesh = icosphere(1)
    with pytest.raises(ParameterError, match="quality"):
        build_rbvh(mesh, "Q9")
    with pytest.raises(ParameterError, match="split"):
        build_rbvh(mesh, split="middle")
    with pytest.raises(ParameterError, match="overlap"):
        build_rbvh(mesh, overlap=0.9)
    with pytest.raises(ParameterError, match="rays"):
        build_rbvh(mesh, rays="sometimes")
    with pytest.raises(ParameterError, match="normals"):
        build_rbvh(PointCloud(np.random.default_rng(0).normal(size=(10, 3))))
    with pytest.raises(ParameterError, match="surface"):
        build_rbvh(np.zeros((3, 3)))


def test_mip_levels_follow_the_footprint_without_cracks(rng):
    mesh = icosphere(5)
    index = build_rbvh(mesh, "Q2", mip_levels=3)
    n = index.n_tiles
    assert index.tiles.shape[0] == 3 * n
    assert np.all(index.tile_res[2 * n:] <= index.tile_res[:n])  # coarser levels are smaller
    d = rng.normal(size=(2000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    fine = raycast(index, -3.0 * d, d)
    assert fine.hit.all() and fine.tile.max() < n  # no footprint: the finest level
    # A footprint of several texels picks the coarsest level, which is crack-free too.
    coarse = raycast(index, -3.0 * d, d, footprint=(0.0, 0.05))
    assert coarse.hit.all() and coarse.tile.min() >= 2 * n
    err = np.abs(np.linalg.norm(coarse.points, axis=1) - 1.0)
    assert err.max() <= 4 * TEXELS * texel(mesh, "Q2") + 1e-3
    # A camera far away uses coarse levels for its wide pixels.
    from sparsecast import Camera
    from sparsecast.surface.render import cast_camera

    hits = cast_camera(index, Camera.look_at((0, -40, 0), (0, 0, 0), fov_y=5.0), 48, 48)
    assert (hits.tile[np.isfinite(hits.t)] >= n).any()


def _mixed_mesh() -> TriangleMesh:
    """A fine plane (tiles) and a coarse box above it (exact triangle leaves)."""
    plane = grid_plane(48)
    box = box_mesh((0.3, 0.3, 0.2), (0.6, 0.7, 0.5), n=1)
    return TriangleMesh(np.concatenate([plane.vertices, box.vertices]),
                        np.concatenate([plane.faces, box.faces + len(plane.vertices)]), "plane+box")


@pytest.mark.parametrize("mip_levels", [1, 3])
def test_wide_layout_finds_the_binary_layouts_hits(rng, mip_levels):
    mesh = _mixed_mesh()
    binary = build_rbvh(mesh, "Q3", layout="binary", mip_levels=mip_levels)
    wide = build_rbvh(mesh, "Q3", mip_levels=mip_levels)
    sb, sw = binary.stats(), wide.stats()
    assert sb["layout"] == "binary" and sw["layout"] == "wide" and wide.node_count.size == 0
    # Same leaves, fewer nodes: the collapse keeps every tile and triangle leaf.
    for key in ("tiles", "tile_leaves", "triangle_leaves", "triangles", "bytes_atlas"):
        assert sw[key] == sb[key], key
    assert sb["tile_leaves"] > 0 and sb["triangle_leaves"] > 0
    assert sw["nodes"] < sb["nodes"] / 2 and sw["wide_depth"] < sb["depth"]
    np.testing.assert_array_equal(wide.bounds, binary.bounds)
    o = np.c_[rng.uniform(-0.05, 1.05, (3000, 2)), rng.uniform(1.0, 2.0, 3000)]
    d = np.c_[rng.normal(0.0, 0.15, (3000, 2)), -np.ones(3000)]
    # A footprint that spans the mip levels, so the leaf's entry distance must match too.
    hb = raycast(binary, o, d, footprint=(0.0, 0.004))
    hw = raycast(wide, o, d, footprint=(0.0, 0.004))
    assert hb.hit.sum() > 1500 and (hb.face >= 0).sum() > 200 and (hb.tile >= 0).sum() > 1000
    np.testing.assert_array_equal(hw.hit, hb.hit)
    # The same surface at the same distance. Where tiles overlap at a seam both hold
    # the surface, and the first one opened wins: the order differs between layouts.
    np.testing.assert_array_equal(hw.tile >= 0, hb.tile >= 0)
    np.testing.assert_array_equal(hw.face, hb.face)
    np.testing.assert_allclose(hw.t[hw.hit], hb.t[hb.hit], rtol=0, atol=1e-6)
    same = hw.tile == hb.tile
    assert same.mean() > 0.9
    np.testing.assert_allclose(hw.t[same & hw.hit], hb.t[same & hb.hit], rtol=0, atol=1e-12)
    np.testing.assert_allclose(hw.normals[same], hb.normals[same], atol=1e-6)


def test_wide_layout_box_test_keeps_axis_parallel_and_face_plane_rays():
    # The wide layout's float32 box test (kernels.simd.slab4, conservative) against
    # the binary layout's float64 one: rays along the axes, in the coarse box's face
    # planes, with components under D_FLUSH, and grazing the plane.
    mesh = _mixed_mesh()
    binary = build_rbvh(mesh, "Q3", layout="binary")
    wide = build_rbvh(mesh, "Q3")
    g = np.linspace(0.0, 1.0, 41)
    xs, ys = np.meshgrid(np.r_[g, 0.3, 0.6], np.r_[g, 0.3, 0.7])
    n = xs.size
    down = (np.c_[xs.ravel(), ys.ravel(), np.full(n, 2.0)], np.tile([0.0, 0.0, -1.0], (n, 1)))
    tiny = (down[0], np.tile([1e-20, -1e-19, -1.0], (n, 1)))
    zs = np.r_[np.linspace(0.0, 0.6, 25), 0.2, 0.5]
    yy, zz = np.meshgrid(np.r_[g, 0.3, 0.7], zs)
    m = yy.size
    along_x = (np.c_[np.full(m, -1.0), yy.ravel(), zz.ravel()], np.tile([1.0, 0.0, 0.0], (m, 1)))
    back_x = (np.c_[np.full(m, 2.0), yy.ravel(), zz.ravel()], np.tile([-1.0, 0.0, 0.0], (m, 1)))
    along_y = (np.c_[yy.ravel(), np.full(m, -1.0), zz.ravel()], np.tile([0.0, 1.0, 0.0], (m, 1)))
    graze = (np.c_[np.full(m, -1.0), yy.ravel(), np.full(m, 1e-9)], np.tile([1.0, 0.0, -1e-9], (m, 1)))
    total_hits = 0
    for o, d in (down, tiny, along_x, back_x, along_y, graze):
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        hb = raycast(binary, o, d)
        hw = raycast(wide, o, d)
        np.testing.assert_array_equal(hw.hit, hb.hit)
        np.testing.assert_array_equal(hw.face, hb.face)
        np.testing.assert_allclose(hw.t[hw.hit], hb.t[hb.hit], rtol=0, atol=1e-6)
        total_hits += int(hw.hit.sum())
    # the box's faces (triangle leaves) and the plane (tiles) were both hit
    assert total_hits > 3000
    assert (raycast(wide, *along_x).face >= 0).sum() > 100


def test_wide_layout_of_a_tree_that_is_one_leaf_and_a_bad_layout():
    # A tetrahedron is one triangle leaf: the wide root holds that one leaf.
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    tet = TriangleMesh(v, np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]]), "tet")
    index = build_rbvh(tet, "Q2")
    s = index.stats()
    assert s["nodes"] == 1 and s["triangle_leaves"] == 1 and s["tiles"] == 0
    hits = raycast(index, [[0.2, 0.2, 2.0], [2.0, 2.0, 2.0]], [[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])
    np.testing.assert_allclose(hits.t, [1.4, np.inf], atol=1e-6)
    with pytest.raises(ParameterError, match="layout"):
        build_rbvh(tet, layout="octree")
