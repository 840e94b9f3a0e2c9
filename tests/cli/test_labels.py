"""Label volumes from the command line: ``--tf labels``, ``--tf labels:IDS``, label JSON files, ``info``."""

from __future__ import annotations

import json

import numpy as np
import pytest

import sparsecast as sc
from cli_runner import run_cli


@pytest.fixture
def seg_file(tmp_path):
    data = np.zeros((20, 22, 24), np.uint8)
    data[3:10, 3:12, 4:12] = 1
    data[8:16, 10:18, 12:20] = 4
    data[2:6, 15:20, 2:6] = 9
    path = tmp_path / "seg[v2].npy"
    sc.save_volume(sc.Volume(data, name="seg"), path)
    return path


def _render(monkeypatch, capsys, tmp_path, seg_file, tf, *extra):
    arr = tmp_path / "img.npy"
    code, out, err = run_cli(monkeypatch, capsys, "render", str(seg_file), "--tf", tf, "--size", "32x32",
                             "--background", "transparent", "-o", str(tmp_path / "img.png"), "--array", str(arr),
                             *extra)
    return code, out, err, (np.load(arr) if code == 0 else None)


def test_smooth_labels_and_clip_cap_like_the_api(monkeypatch, capsys, tmp_path, seg_file):
    plane = ((12.0, 11.0, 10.0), (-1.0, 0.0, 0.3))
    code, _, err, rgba = _render(monkeypatch, capsys, tmp_path, seg_file, "labels:1,4", "--smooth-labels",
                                 "--clip-cap", "--clip-plane", ",".join(map(str, (*plane[0], *plane[1]))))
    assert code == 0, err
    vol = sc.load_volume(seg_file)
    tf = sc.TransferFunction.labels([1, 4], name="labels:1,4", smooth=True)
    cam = sc.Camera.orbit(vol, 30, 20)
    ref = sc.render(vol, tf, cam, 32, 32, background="transparent", clip_planes=[plane], clip_cap=True)
    np.testing.assert_allclose(rgba, ref.rgba, atol=1e-6)
    sharp = sc.render(vol, tf.smoothed(False), cam, 32, 32, background="transparent", clip_planes=[plane])
    assert np.abs(ref.rgba - sharp.rgba).max() > 0.05


def test_smooth_labels_need_a_label_tf(monkeypatch, capsys, tmp_path, seg_file):
    code, _, err, _ = _render(monkeypatch, capsys, tmp_path, seg_file, "viridis", "--smooth-labels")
    assert code == 2 and err.count("error:") == 1
    assert "--smooth-labels: applies to label TFs" in err and "--tf viridis" in err


def test_tf_labels_colours_every_id_but_background_like_the_api(monkeypatch, capsys, tmp_path, seg_file):
    code, out, err, rgba = _render(monkeypatch, capsys, tmp_path, seg_file, "labels")
    assert code == 0, err
    vol = sc.load_volume(seg_file)
    tf = sc.TransferFunction.labels([1, 4, 9])
    ref = sc.render(vol, tf, sc.Camera.orbit(vol, 30, 20), 32, 32, background="transparent")
    np.testing.assert_allclose(rgba, ref.rgba, atol=1e-6)


def test_tf_label_subset_hides_the_others(monkeypatch, capsys, tmp_path, seg_file):
    code, _, err, all_ids = _render(monkeypatch, capsys, tmp_path, seg_file, "labels")
    code2, _, err2, only4 = _render(monkeypatch, capsys, tmp_path, seg_file, "labels:4")
    assert code == 0 and code2 == 0, err + err2
    assert 0 < (only4[..., 3] > 0).sum() < (all_ids[..., 3] > 0).sum()


def test_label_json_file(monkeypatch, capsys, tmp_path, seg_file):
    spec = tmp_path / "organs.json"
    spec.write_text(json.dumps({"format": "sparsecast-labels/1", "labels": {"4": "red", "9": [0, 0, 1, 0.5]}}))
    code, _, err, rgba = _render(monkeypatch, capsys, tmp_path, seg_file, str(spec))
    assert code == 0, err
    lit = rgba[rgba[..., 3] > 0.9]
    assert lit.size and lit[:, 1].max() == 0.0  # red and blue only: ids never blend


@pytest.mark.parametrize("tf, fragment", [
    ("labels:4,5", "id(s) 5 do not occur in seg[v2]; it holds 0, 1, 4, 9"),
    ("labels:x", "expected labels:ID,ID,..."),
])
def test_bad_label_specs(monkeypatch, capsys, tmp_path, seg_file, tf, fragment):
    code, _, err, _ = _render(monkeypatch, capsys, tmp_path, seg_file, tf)
    assert code == 2
    assert fragment in err


def test_tf_labels_on_a_scalar_field_is_refused(monkeypatch, capsys, tmp_path, small_volume_file):
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--tf", "labels",
                           "-o", str(tmp_path / "x.png"))
    assert code == 2
    assert "is not a label volume" in err
    assert not (tmp_path / "x.png").exists()


def test_info_lists_labels_and_voxel_counts(monkeypatch, capsys, seg_file):
    code, out, err = run_cli(monkeypatch, capsys, "info", str(seg_file), "--tf", "labels:1,9")
    assert code == 0, err
    data = np.load(seg_file)
    line = next(l for l in out.splitlines() if l.strip().startswith("labels"))
    assert f"4 ids: 0 ({(data == 0).sum()} voxels)" in line
    assert f"1 ({(data == 1).sum()} voxels, shown)" in line
    assert f"4 ({(data == 4).sum()} voxels)" in line
    assert "seg[v2].npy" in out  # the path as written
