"""Mesh and point-cloud readers: formats, and one clear error per bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from sparsecast.errors import FileFormatError
from sparsecast.io.meshes import load_mesh, load_points, load_surface
from sparsecast.surface.mesh import DEGENERATE_FRACTION, DegenerateFacesWarning, MeshDataError, PointCloud, TriangleMesh

TET_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TET_F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]])


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".stl", ".glb", ".off"])
def test_formats_round_trip(tmp_path, suffix):
    path = tmp_path / f"tet{suffix}"
    trimesh.Trimesh(TET_V, TET_F, process=False).export(path)
    mesh = load_mesh(path)
    assert mesh.n_triangles == 4
    np.testing.assert_allclose(mesh.area, 1.5 + np.sqrt(3) / 2)
    assert mesh.source == str(path)


def test_shared_bunny_loads(shared_file):
    path = shared_file("stanford_bunny.ply")
    mesh = load_mesh(path)
    assert mesh.n_triangles == 69451


def test_shared_dragon_loads_with_its_few_degenerate_faces(shared_data_dir):
    """The Stanford dragon carries a handful of zero-area triangles (the other shared meshes
    none): it loads with a warning that counts them."""
    path = shared_data_dir / "stanford_dragon_871k.ply"
    if not path.is_file():
        pytest.skip("shared data not present")
    with pytest.warns(DegenerateFacesWarning) as caught:
        mesh = load_mesh(path)
    w = next(c.message for c in caught if isinstance(c.message, DegenerateFacesWarning))
    assert not w.dropped and w.count == mesh.degenerate_faces.size
    assert 0 < w.count <= DEGENERATE_FRACTION * mesh.n_triangles and w.total == mesh.n_triangles
    clean, dropped = TriangleMesh.cleaned(mesh.vertices, mesh.faces)  # what drop_degenerate=True keeps
    assert dropped == w.count and clean.n_triangles == mesh.n_triangles - w.count
    assert clean.degenerate_faces.size == 0


def test_missing_and_unsupported_files(tmp_path):
    with pytest.raises(FileFormatError, match="file not found"):
        load_mesh(tmp_path / "none.ply")
    (tmp_path / "x.vtk").write_text("x")
    with pytest.raises(FileFormatError, match="unsupported suffix"):
        load_mesh(tmp_path / "x.vtk")
    (tmp_path / "bad.ply").write_bytes(b"ply\nformat garbage\n")
    with pytest.raises(FileFormatError, match="bad.ply"):
        load_mesh(tmp_path / "bad.ply")


def test_empty_mesh_file(tmp_path):
    path = tmp_path / "empty.obj"
    path.write_text("# nothing here\n")
    with pytest.raises((FileFormatError, MeshDataError), match="empty.obj"):
        load_mesh(path)


def test_nan_vertices_are_named(tmp_path):
    path = tmp_path / "nan.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    with pytest.raises(MeshDataError, match=r"nan\.obj.*NaN"):
        load_mesh(path)


def test_degenerate_triangles_error_or_drop(tmp_path):
    path = tmp_path / "degen.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n")  # second is collinear
    with pytest.raises(MeshDataError, match=r"degen\.obj: 1 of 2 triangles are degenerate"):
        load_mesh(path)
    with pytest.warns(UserWarning, match="dropped 1 degenerate"):
        mesh = load_mesh(path, drop_degenerate=True)
    assert mesh.n_triangles == 1


def test_non_manifold_mesh_loads_with_a_warning(tmp_path):
    # Three triangles on one edge: non-manifold, still fine to ray cast.
    path = tmp_path / "fan.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 2 5\n")
    with pytest.warns(UserWarning, match="non-manifold"):
        mesh = load_mesh(path)
    assert mesh.n_triangles == 3


def test_container_validation():
    with pytest.raises(MeshDataError, match="face indices"):
        TriangleMesh(TET_V, TET_F + 1, "t")
    with pytest.raises(MeshDataError, match="no faces"):
        TriangleMesh(TET_V, np.zeros((0, 3), int), "t")
    with pytest.raises(MeshDataError, match="shape"):
        TriangleMesh(TET_V[:, :2], TET_F, "t")
    with pytest.raises(MeshDataError, match="normals"):
        PointCloud(TET_V, np.zeros((4, 3)))


def test_point_clouds_from_npy_and_ply(tmp_path):
    pts = np.random.default_rng(0).normal(size=(50, 3))
    nrm = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    np.save(tmp_path / "p.npy", np.c_[pts, nrm])
    cloud = load_points(tmp_path / "p.npy", radius=0.1)
    np.testing.assert_allclose(cloud.normals, nrm)
    assert np.all(cloud.radii == 0.1)
    np.save(tmp_path / "bad.npy", np.zeros((5, 4)))
    with pytest.raises(MeshDataError, match=r"bad\.npy.*\(n, 3\) or \(n, 6\)"):
        load_points(tmp_path / "bad.npy")
    trimesh.Trimesh(TET_V, TET_F, process=False).export(tmp_path / "tet.ply")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cloud = load_points(tmp_path / "tet.ply")
    assert len(cloud.points) == 4 and cloud.normals is not None


def test_points_without_normals_get_estimated_normals(tmp_path, rng):
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    trimesh.PointCloud(u).export(tmp_path / "scan.ply")  # vertices only, as a raw range scan
    np.save(tmp_path / "scan.npy", u)
    for name in ("scan.ply", "scan.npy"):
        cloud = load_points(tmp_path / name)
        assert cloud.normals_estimated
        assert np.sum(cloud.normals * u, axis=1).min() > 0.95
    np.save(tmp_path / "two.npy", u[:2])
    with pytest.raises(MeshDataError, match="at least 3"):
        load_points(tmp_path / "two.npy")
    np.save(tmp_path / "n.npy", np.c_[u, u])
    assert not load_points(tmp_path / "n.npy").normals_estimated


def test_ascii_ply_normals_are_read(tmp_path):
    (tmp_path / "a.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\nend_header\n"
        "0 0 0 0 0 1\n1 0 0 0 1 0\n0 1 0 1 0 0\n")
    cloud = load_points(tmp_path / "a.ply", radius=0.5)
    assert not cloud.normals_estimated
    np.testing.assert_allclose(cloud.normals, [[0, 0, 1], [0, 1, 0], [1, 0, 0]])


def test_load_surface_tells_points_from_meshes(tmp_path, rng):
    trimesh.Trimesh(TET_V, TET_F, process=False).export(tmp_path / "tet.ply")
    trimesh.PointCloud(rng.normal(size=(50, 3))).export(tmp_path / "pts.ply")
    assert isinstance(load_surface(tmp_path / "tet.ply"), TriangleMesh)
    cloud = load_surface(tmp_path / "pts.ply", radius=0.2)
    assert isinstance(cloud, PointCloud) and len(cloud.points) == 50 and cloud.normals_estimated
    assert np.all(cloud.radii == 0.2)


def test_shared_scans_load_as_points(shared_data_dir):
    for name, n in (("bunny_scan_bun000_40k_points.ply", 40256), ("dark_matter_halo_32k_points.ply", 32314)):
        path = shared_data_dir / name
        if not path.is_file():
            pytest.skip("shared data not present")
        cloud = load_surface(path)
        assert isinstance(cloud, PointCloud) and len(cloud.points) == n and cloud.normals_estimated
