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


def test_spatial_splits_render_the_same_mesh(monkeypatch, capsys, tmp_path):
    path = tmp_path / "sphere.ply"
    s = icosphere(3)
    trimesh.Trimesh(s.vertices, s.faces, process=False).export(path)
    images = {}
    for splits in ("0", "2"):
        out = tmp_path / f"s{splits}.png"
        code, stdout, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", "bvh", "--splits", splits,
                                    "--size", "40x30", "-o", str(out))
        assert code == 0, err
        assert ("spatial splits" in stdout) == (splits != "0")
        with PILImage.open(out) as im:
            images[splits] = np.asarray(im).astype(int)
    # The same hits: at most an edge pixel's shading differs (a tie between two faces).
    assert np.abs(images["0"] - images["2"]).max() <= 2
    for bad, words in ((["--splits", "1"], "--index bvh"), (["--index", "bvh", "--splits", "-1"], "0..4")):
        code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), *bad, "-o", str(tmp_path / "x.png"))
        assert code == 2 and "--splits" in err and words in err, err
        assert not (tmp_path / "x.png").exists()


def test_render_mesh_errors_are_one_line(monkeypatch, capsys, tmp_path):
    code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(tmp_path / "none.ply"), "-o", str(tmp_path / "o.png"))
    assert code == 2 and "none.ply" in err
    path = tmp_path / "s.ply"
    s = icosphere(1)
    trimesh.Trimesh(s.vertices, s.faces, process=False).export(path)
    code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", "kdtree", "-o", str(tmp_path / "o.png"))
    assert code == 2 and "--index" in err
    assert not (tmp_path / "o.png").exists()


def _sphere_file(tmp_path, degenerate: int):
    """A 1280-face sphere PLY plus ``degenerate`` repeated-vertex faces."""
    from sparsecast.surface.mesh import subdivide

    s = subdivide(icosphere(2), 1)
    f = np.vstack([s.faces, [[int(a), int(a), int(b)] for a, b in s.faces[:degenerate, :2]]]) if degenerate else s.faces
    path = tmp_path / f"degen{degenerate}.ply"
    trimesh.Trimesh(s.vertices, f, process=False).export(path)
    return path, len(f)


def test_a_few_degenerate_faces_are_a_warning(monkeypatch, capsys, tmp_path):
    path, n = _sphere_file(tmp_path, 1)  # 1 of 1281: under 0.1 %
    out = tmp_path / "o.png"
    code, stdout, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", "bvh", "--size", "32x32",
                                "-o", str(out))
    assert code == 0, err
    assert err.startswith("warning: ") and f"1 of {n} triangles are degenerate" in err and "--drop-degenerate" in err
    assert "drop_degenerate" not in err and out.exists()


def test_many_degenerate_faces_error_names_the_flag_and_drop_renders(monkeypatch, capsys, tmp_path):
    path, n = _sphere_file(tmp_path, 3)  # 3 of 1283: over 0.1 %
    out = tmp_path / "o.png"
    code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", "bvh", "--size", "32x32",
                           "-o", str(out))
    assert code == 2 and err.startswith("error: ") and len(err.strip().splitlines()) == 1
    assert f"3 of {n} triangles are degenerate" in err and "--drop-degenerate" in err and "drop_degenerate=" not in err
    assert str(path) in err and not out.exists()
    code, stdout, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", "bvh", "--size", "32x32",
                                "--drop-degenerate", "-o", str(out))
    assert code == 0, err
    assert f"{n - 3} triangles after dropping 3 degenerate" in stdout and "warning" not in err and out.exists()


def test_up_axis_and_the_deprecated_y_up(monkeypatch, capsys, tmp_path):
    """--up y renders a y-up mesh as --y-up did (the same image), differently from --up z;
    --y-up together with --up, and a bad axis, are one-line errors."""
    s = icosphere(2)
    v = s.vertices.copy()
    v[v[:, 1] > 0.3, 1] += 0.8  # a y-up mesh: tall along +y
    path = tmp_path / "tall.ply"
    trimesh.Trimesh(v, s.faces, process=False).export(path)
    images = {}
    for name, flags in (("up-y", ["--up", "y"]), ("y-up", ["--y-up"]), ("up-z", [])):
        out = tmp_path / f"{name}.npy"
        code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--index", "bvh", "--mode", "depth",
                               "--size", "48x48", "--azimuth", "0", "--elevation", "0", *flags, "-o", str(out))
        assert code == 0, err
        images[name] = np.load(out)
    np.testing.assert_array_equal(images["up-y"], images["y-up"])
    hit = images["up-y"][..., 0] > 0  # depth: white near, black background
    rows, cols = np.flatnonzero(hit.any(axis=1)), np.flatnonzero(hit.any(axis=0))
    assert rows.size > cols.size + 5  # upright: taller than wide on screen
    assert not np.array_equal(images["up-y"], images["up-z"])
    code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--up", "w", "-o", str(tmp_path / "x.png"))
    assert code == 2 and "--up" in err and "'w'" in err
    code, _, err = run_cli(monkeypatch, capsys, "render-mesh", str(path), "--up", "y", "--y-up",
                           "-o", str(tmp_path / "x.png"))
    assert code == 2 and "--up" in err


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
