"""Hostile inputs on the command line (issue 14): one line, exit status 2, no traceback."""

from __future__ import annotations

import os

import numpy as np

from cli_runner import run_cli


def _nhdr(path, data_file):
    path.write_bytes(b"NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4 4\nencoding: raw\nendian: little\ndata file: "
                     + data_file.encode() + b"\n")
    return path


def test_outside_data_file_needs_the_option(monkeypatch, capsys, tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "d.raw").write_bytes(np.arange(64, dtype="<f4").tobytes())
    hdr = _nhdr(tmp_path / "sub" / "h.nhdr", "../d.raw")
    code, _, err = run_cli(monkeypatch, capsys, "info", str(hdr))
    assert code == 2 and "outside the header's folder" in err and "--allow-outside-data" in err
    assert "Traceback" not in err
    code, out, err = run_cli(monkeypatch, capsys, "info", str(hdr), "--allow-outside-data")
    assert code == 0, err
    assert "4 x 4 x 4" in out


def test_fifo_volume_is_refused_not_waited_on(monkeypatch, capsys, tmp_path):
    os.mkfifo(tmp_path / "p.nrrd")
    code, _, err = run_cli(monkeypatch, capsys, "info", str(tmp_path / "p.nrrd"))
    assert code == 2 and "not a regular file" in err


def test_full_width_digits_and_orphan_raw_options(monkeypatch, capsys):
    from sparsecast.cli.parse import parse_dims, parse_size
    from sparsecast.errors import ParameterError
    import pytest

    with pytest.raises(ParameterError, match="--size"):
        parse_size("３２x３２")
    with pytest.raises(ParameterError, match="--dims"):
        parse_dims("４x4x4")
    assert parse_size("32x16") == (32, 16)
    for opt, value in (("--spacing", "1,1,2"), ("--dims", "4x4x4"), ("--dtype", "uint8")):
        code, _, err = run_cli(monkeypatch, capsys, "info", opt, value)
        assert code == 2 and opt in err and "only to a volume FILE" in err
    code, _, err = run_cli(monkeypatch, capsys, "render", "--size", "３２x３２")
    assert code == 2 and "--size" in err


def test_nonfinite_voxels_from_the_command_line(monkeypatch, capsys, tmp_path):
    """A float volume with NaN/Inf fails with the count and the option that helps; with
    ``--nonfinite replace`` it renders, NaN and -Inf as the finite minimum, +Inf as the maximum."""
    from PIL import Image

    import sparsecast as sc

    vol = sc.datasets.nbody_blobs(16, n_clusters=1, blobs_per_cluster=4, seed=2)
    data = np.array(vol.data, np.float32)
    lo, hi = float(data.min()), float(data.max())
    bad = data.copy()
    bad[0, 0, :3] = (np.nan, -np.inf, np.inf)
    np.save(tmp_path / "bad.npy", bad)
    code, _, err = run_cli(monkeypatch, capsys, "render", str(tmp_path / "bad.npy"), "-o", str(tmp_path / "a.png"),
                           "--size", "16x16")
    assert code == 2 and "3 voxel(s) are NaN or Inf" in err and "--nonfinite replace" in err
    # The file named as every loader error names it: quoted, so that a name with spaces
    # or colons reads unambiguously.
    assert f"{str(tmp_path / 'bad.npy')!r}: 3 voxel(s)" in err
    assert not (tmp_path / "a.png").exists() and "Traceback" not in err
    code, _, err = run_cli(monkeypatch, capsys, "render", str(tmp_path / "bad.npy"), "--nonfinite", "maybe")
    assert code == 2 and "--nonfinite" in err and "'maybe'" in err and "'raise' or 'replace'" in err

    fixed = data.copy()
    fixed[0, 0, :3] = (lo, lo, hi)
    np.save(tmp_path / "fixed.npy", fixed)
    images = []
    for name in ("bad", "fixed"):
        args = ["--nonfinite", "replace"] if name == "bad" else []
        code, _, err = run_cli(monkeypatch, capsys, "render", str(tmp_path / f"{name}.npy"), *args,
                               "-o", str(tmp_path / f"{name}.png"), "--size", "24x24", "--array",
                               str(tmp_path / f"{name}.rgba.npy"))
        assert code == 0, err
        images.append(np.load(tmp_path / f"{name}.rgba.npy"))
        assert Image.open(tmp_path / f"{name}.png").size == (24, 24)
    assert np.array_equal(images[0], images[1])  # replaced exactly as documented
    code, out, err = run_cli(monkeypatch, capsys, "info", str(tmp_path / "bad.npy"), "--nonfinite", "replace")
    assert code == 0, err
    assert "16 x 16 x 16" in out


def test_nonfinite_series_steps(monkeypatch, capsys, tmp_path):
    """``--nonfinite`` reaches every step of a 4-D .npy series."""
    steps = np.random.default_rng(1).random((2, 6, 6, 6)).astype(np.float32)
    steps[1, 2, 2, 2] = np.nan
    np.save(tmp_path / "s.npy", steps)
    code, _, err = run_cli(monkeypatch, capsys, "render", str(tmp_path / "s.npy"), "--time", "1",
                           "-o", str(tmp_path / "a.png"), "--size", "8x8")
    assert code == 2 and "NaN or Inf" in err and "--nonfinite replace" in err
    code, _, err = run_cli(monkeypatch, capsys, "render", str(tmp_path / "s.npy"), "--time", "1",
                           "--nonfinite", "replace", "-o", str(tmp_path / "a.png"), "--size", "8x8")
    assert code == 0, err
    assert (tmp_path / "a.png").is_file()
