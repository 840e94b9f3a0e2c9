"""`sparsecast render-points`: particle files to images, coloured by an attribute; one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image as PILImage

from cli_runner import run_cli


def _catalogue(tmp_path, n=600):
    """A generated star catalogue: a bright cluster in a field of faint stars (x, y, z, mag)."""
    rng = np.random.default_rng(11)
    pos = np.concatenate([rng.normal(0.0, 0.1, (n // 2, 3)), rng.uniform(-1, 1, (n - n // 2, 3))])
    mag = np.concatenate([rng.normal(3.0, 0.3, n // 2), rng.normal(9.0, 0.3, n - n // 2)])
    path = tmp_path / "stars.csv"
    path.write_text("x,y,z,mag\n" + "\n".join(f"{x:.6f},{y:.6f},{z:.6f},{m:.3f}" for (x, y, z), m in zip(pos, mag)))
    return path


def test_catalogue_coloured_by_magnitude(monkeypatch, capsys, tmp_path):
    path = _catalogue(tmp_path)
    out = tmp_path / "stars.png"
    code, stdout, err = run_cli(monkeypatch, capsys, "render-points", str(path), "--color-by", "mag", "--cmap",
                                "viridis", "--size", "48x40", "--elevation", "90", "--projection", "orthographic",
                                "-o", str(out))
    assert code == 0, err
    assert "600 particles" in stdout and "colour by mag through viridis over [" in stdout
    assert "median distance to the 2nd-nearest neighbour" in stdout and "render" in stdout
    with PILImage.open(out) as im:
        assert im.size == (48, 40)
        a = np.asarray(im.convert("RGB")).astype(int)
    # The cluster (bright stars, low magnitude: viridis' purple end, blue > green) sits in
    # the middle; the field's faint stars around it take the yellow end (green > blue).
    centre = a[17:23, 21:27].reshape(-1, 3).mean(0)
    ring = a.copy()
    ring[10:30, 14:34] = 0
    outer = ring[ring.sum(-1) > 30].mean(0)
    assert centre[2] > 1.3 * centre[1] and outer[1] > 2 * outer[2]


def test_auto_colour_and_given_radius(monkeypatch, capsys, tmp_path):
    rng = np.random.default_rng(2)
    pts = rng.normal(size=(300, 3))
    trimesh.PointCloud(pts).export(tmp_path / "halo.ply")
    out = tmp_path / "o.png"
    code, stdout, err = run_cli(monkeypatch, capsys, "render-points", str(tmp_path / "halo.ply"), "--radius", "0.2",
                                "--opacity", "0.5", "--up", "y", "--size", "32x32", "-o", str(out))
    assert code == 0, err
    assert "radius 0.2 (given)" in stdout and "colour by log_density (16 neighbours) through inferno" in stdout
    assert "opacity 0.5" in stdout
    cols = (rng.uniform(0, 1, (300, 4)) * 255).astype(np.uint8)
    trimesh.PointCloud(pts, colors=cols).export(tmp_path / "col.ply")
    code, stdout, err = run_cli(monkeypatch, capsys, "render-points", str(tmp_path / "col.ply"), "--size", "32x32",
                                "-o", str(out))
    assert code == 0, err
    assert "file colours" in stdout
    with PILImage.open(out) as im:
        assert np.asarray(im.convert("RGB")).max() > 0


@pytest.mark.parametrize("args, words", [
    (["--color-by", "brightness"], ["--color-by", "no attribute 'brightness'", "available: mag, log_density"]),
    (["--opacity", "0"], ["opacity"]),
    (["--cmap", "rainbowz"], ["cmap", "rainbowz"]),
    (["--up", "w"], ["up", "x, y, z"]),
    (["--color-range", "1"], ["--color-range"]),
])
def test_bad_options_are_one_line(monkeypatch, capsys, tmp_path, args, words):
    path = _catalogue(tmp_path, 60)
    out = tmp_path / "o.png"
    code, _, err = run_cli(monkeypatch, capsys, "render-points", str(path), *args, "--size", "16x16", "-o", str(out))
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1
    for w in words:
        assert w in err
    assert not out.exists()


def test_empty_files(monkeypatch, capsys, tmp_path):
    (tmp_path / "head.csv").write_text("x,y,z,mag\n")
    np.save(tmp_path / "none.npy", np.zeros((0, 3)))
    for name, word in (("head.csv", "no particle rows"), ("none.npy", "holds no particles")):
        code, _, err = run_cli(monkeypatch, capsys, "render-points", str(tmp_path / name), "-o", str(tmp_path / "o.png"))
        assert code == 2 and name in err and word in err, err
    assert not (tmp_path / "o.png").exists()


def test_shared_halo_renders(monkeypatch, capsys, tmp_path, shared_data_dir):
    path = shared_data_dir / "dark_matter_halo_32k_points.ply"
    if not path.is_file():
        pytest.skip("shared data not present")
    code, stdout, err = run_cli(monkeypatch, capsys, "render-points", str(path), "--size", "48x48",
                                "-o", str(tmp_path / "h.png"))
    assert code == 0, err
    assert "32314 particles" in stdout and "log_density" in stdout
