"""`sparsecast render-mesh`: a mesh file to an image with either surface index; one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image as PILImage

from cli_runner import run_cli
from sparsecast.surface.mesh import icosphere


@pytest.mark.parametrize("index", ["rbvh", "bvh"])
def test_render_mesh_command(monkeypatch, capsys, tmp_path, index):
    path = tmp_path / "sphere.ply"
    s = icosphere(3)
    trimesh.Trimesh(s.vertices, s.faces, process=False).export(path)
    out = tmp_path / "out.png"
    code, stdout, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", index,
                                "--quality", "Q3", "--size", "40x30", "-o", str(out))
    assert code == 0, err
    assert f"index {index}" in stdout and "Mrays/s" in stdout
    with PILImage.open(out) as im:
        assert im.size == (40, 30)
        assert np.asarray(im)[15, 20, 0] > 0  # the sphere is drawn


def test_render_mesh_errors_are_one_line(monkeypatch, capsys, tmp_path):
    code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(tmp_path / "none.ply"), "-o", str(tmp_path / "o.png"))
    assert code == 2 and "none.ply" in err
    path = tmp_path / "s.ply"
    s = icosphere(1)
    trimesh.Trimesh(s.vertices, s.faces, process=False).export(path)
    code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", "kdtree", "-o", str(tmp_path / "o.png"))
    assert code == 2 and "--index" in err
    assert not (tmp_path / "o.png").exists()


@pytest.mark.parametrize("index", ["rbvh", "bvh"])
def test_a_ply_of_points_renders_as_points(monkeypatch, capsys, tmp_path, index):
    """A PLY with vertices but no faces and no normals (a raw scan): auto-detected,
    normals estimated, rendered with either index, y-up accepted."""
    rng = np.random.default_rng(4)
    u = rng.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    path = tmp_path / "scan.ply"
    trimesh.PointCloud(u).export(path)
    out = tmp_path / "out.png"
    code, stdout, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", index, "--y-up",
                                "--size", "40x30", "-o", str(out))
    assert code == 0, err
    assert "3000 points (no faces: rendered as points)" in stdout and "normals estimated" in stdout
    with PILImage.open(out) as im:
        a = np.asarray(im)
        assert a[15, 20, 0] > 0 and a[0, 0, 0] == 0  # the ball is drawn, the corner is background
    code, stdout, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--points", "--index", index,
                                "--radius", "0.05", "--size", "40x30", "-o", str(out))
    assert code == 0, err
    assert "3000 points, disc radius 0.05" in stdout


def test_radius_for_a_mesh_is_refused(monkeypatch, capsys, tmp_path):
    path = tmp_path / "s.ply"
    s = icosphere(1)
    trimesh.Trimesh(s.vertices, s.faces, process=False).export(path)
    code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--radius", "0.1", "-o", str(tmp_path / "o.png"))
    assert code == 2 and "--radius" in err and "s.ply" in err and "80 triangles" in err
