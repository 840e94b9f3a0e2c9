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
        assert code == 2 and opt in err and "only apply to a volume FILE" in err
    code, _, err = run_cli(monkeypatch, capsys, "render", "--size", "３２x３２")
    assert code == 2 and "--size" in err
