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
