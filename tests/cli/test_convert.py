"""``sparsecast convert``: chunked Zarr and OME-Zarr output, atomic, refusing to overwrite."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.io import open_source
from sparsecast._util.atomic import TEMP_PREFIX

from cli_runner import run_cli


def _input(tmp_path, dtype="uint16", shape=(37, 50, 23)):
    rng = np.random.default_rng(0)
    a = (rng.random(shape) * 1000).astype(dtype)
    a[rng.random(shape) < 0.5] = 0
    path = sc.save_volume(sc.Volume(a, spacing=(0.5, 1.0, 2.5), origin=(1, 2, 3)), tmp_path / "in.nrrd",
                          compress=False)
    return a, path


@pytest.mark.parametrize("dtype", ["uint8", "uint16", "float32"])
def test_convert_to_zarr_keeps_values_and_geometry(monkeypatch, capsys, tmp_path, dtype):
    a, path = _input(tmp_path, dtype)
    code, out, err = run_cli(monkeypatch, capsys, "convert", str(path), str(tmp_path / "o.zarr"), "--chunks", "16")
    assert code == 0, err
    assert "23 x 50 x 37" in out and "chunks 16x16x16" in out
    src = open_source(tmp_path / "o.zarr")
    assert src.chunks == (16, 16, 16) and src.dtype == a.dtype
    np.testing.assert_array_equal(src.array[...], a)
    np.testing.assert_array_equal(src.spacing, [0.5, 1.0, 2.5])
    np.testing.assert_array_equal(src.origin, [1, 2, 3])


def test_convert_ome_pyramid_mean_and_labels(monkeypatch, capsys, tmp_path):
    a, path = _input(tmp_path, "uint8", (150, 70, 66))
    code, out, err = run_cli(monkeypatch, capsys, "convert", str(path), str(tmp_path / "o.zarr"), "--ome")
    assert code == 0, err
    assert "3 levels" in out
    levels = [open_source(tmp_path / "o.zarr", level=i) for i in range(3)]
    assert [s.shape for s in levels] == [(150, 70, 66), (75, 35, 33), (38, 18, 17)]
    np.testing.assert_array_equal(levels[0].array[...], a)
    mean = a[:, :70, :66].reshape(75, 2, 35, 2, 33, 2).mean(axis=(1, 3, 5))
    np.testing.assert_array_equal(levels[1].array[...], np.rint(mean).astype(np.uint8))
    np.testing.assert_array_equal(levels[2].spacing, [2.0, 4.0, 10.0])
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(path), str(tmp_path / "l.zarr"), "--ome", "--labels")
    assert code == 0, err
    np.testing.assert_array_equal(open_source(tmp_path / "l.zarr", level=2).array[...], a[::4, ::4, ::4])
    np.testing.assert_array_equal(open_source(tmp_path / "l.zarr", level=2).origin, [1, 2, 3])


def test_convert_from_a_lazy_source_and_an_ome_level(monkeypatch, capsys, tmp_path):
    a, path = _input(tmp_path, "float32", (140, 20, 30))
    assert run_cli(monkeypatch, capsys, "convert", str(path), str(tmp_path / "o.zarr"), "--ome")[0] == 0
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(tmp_path / "o.zarr"), str(tmp_path / "l1.zarr"),
                           "--level", "1", "--chunks", "8")
    assert code == 0, err
    l1 = open_source(tmp_path / "l1.zarr")
    np.testing.assert_array_equal(l1.array[...], open_source(tmp_path / "o.zarr", level=1).array[...])
    np.testing.assert_array_equal(l1.spacing, [1.0, 2.0, 5.0])  # (0.5, 1, 2.5) x 2
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(tmp_path / "o.zarr"), str(tmp_path / "x.zarr"),
                           "--level", "7")
    assert code == 2 and "no level 7" in err and "1: '1' (70, 10, 15)" in err


def test_convert_refuses_to_overwrite_unless_forced(monkeypatch, capsys, tmp_path):
    a, path = _input(tmp_path)
    target = tmp_path / "o.zarr"
    assert run_cli(monkeypatch, capsys, "convert", str(path), str(target))[0] == 0
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(path), str(target), "--chunks", "8")
    assert code == 2 and err.startswith("error: ") and "exists" in err and "--force" in err
    assert open_source(target).chunks == (37, 50, 23)  # the first store, untouched (64 clipped to the shape)
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(path), str(target), "--chunks", "8", "--force")
    assert code == 0, err
    assert open_source(target).chunks == (8, 8, 8)
    (tmp_path / "mine").mkdir()
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(path), str(tmp_path / "mine"), "--force")
    assert code == 2 and "is not a Zarr store" in err


def test_convert_never_writes_into_its_input(monkeypatch, capsys, tmp_path):
    a, path = _input(tmp_path)
    store = tmp_path / "o.zarr"
    assert run_cli(monkeypatch, capsys, "convert", str(path), str(store))[0] == 0
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(store), str(store), "--force")
    assert code == 2 and "a source is never written to" in err
    np.testing.assert_array_equal(open_source(store).array[...], a)


def test_failed_convert_leaves_nothing(monkeypatch, capsys, tmp_path):
    a, path = _input(tmp_path)
    store = tmp_path / "o.zarr"
    assert run_cli(monkeypatch, capsys, "convert", str(path), str(store), "--chunks", "16")[0] == 0
    (store / "c" / "1" / "0" / "0").unlink()
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(store), str(tmp_path / "copy.zarr"))
    assert code == 2 and "chunk 'c/1/0/0'" in err and "missing" in err
    assert not (tmp_path / "copy.zarr").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(TEMP_PREFIX)]


def test_convert_in_memory_formats_and_gzip_nrrd(monkeypatch, capsys, tmp_path):
    rng = np.random.default_rng(2)
    a = (rng.random((9, 10, 11)) * 50).astype(np.int16)
    for name in ("in.nii.gz", "in.tif", "gz.nrrd"):
        path = sc.save_volume(sc.Volume(a), tmp_path / name)
        code, _, err = run_cli(monkeypatch, capsys, "convert", str(path), str(tmp_path / f"{name}.zarr"))
        assert code == 0, (name, err)
        np.testing.assert_array_equal(open_source(tmp_path / f"{name}.zarr").array[...], a)
