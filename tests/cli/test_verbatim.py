"""CLI messages print user-supplied text as written: square brackets are not rich
markup (issue 15, item 6)."""

from __future__ import annotations

import sys

import numpy as np

import sparsecast as sc
from cli_runner import run_cli


def _flat(text: str) -> str:
    return " ".join(text.split())  # rich wraps long lines


def test_missing_file_with_brackets(monkeypatch, capsys, tmp_path):
    code, _, err = run_cli(monkeypatch, capsys, "render", str(tmp_path / "scan[v2].nrrd"))
    assert code == 2 and "scan[v2].nrrd" in err


def test_output_name_with_brackets(monkeypatch, capsys, tmp_path):
    target = tmp_path / "out[red].png"
    code, out, err = run_cli(monkeypatch, capsys, "render", "--size", "8x8", "-o", str(target))
    assert code == 0, err
    assert target.is_file() and f"wrote {target}" in _flat(out)


def test_unknown_preset_and_tf_file_with_brackets(monkeypatch, capsys, tmp_path):
    code, _, err = run_cli(monkeypatch, capsys, "render", "--size", "8x8", "--tf", "bone[x]",
                           "-o", str(tmp_path / "a.png"))
    assert code == 2 and "'bone[x]'" in err
    clear = sc.TransferFunction([(0, 1, 1, 1, 0), (1, 1, 1, 1, 0)]).save(tmp_path / "clear[b].json")
    code, _, err = run_cli(monkeypatch, capsys, "render", "--size", "8x8", "--tf", str(clear),
                           "-o", str(tmp_path / "b.png"))
    assert code == 0 and "clear[b].json" in err and "warning:" in err


def test_info_prints_names_with_brackets(monkeypatch, capsys, tmp_path):
    path = tmp_path / "scan[bold]v2.npy"
    sc.save_volume(sc.Volume(np.zeros((4, 5, 6), np.float32)), path)
    code, out, err = run_cli(monkeypatch, capsys, "info", str(path))
    assert code == 0, err
    assert str(path) in _flat(out)


def test_bad_index_option_value_with_brackets(monkeypatch, capsys, tmp_path):
    code, _, err = run_cli(monkeypatch, capsys, "render", "--size", "8x8", "--index", "bih:mode=[fast]",
                           "-o", str(tmp_path / "a.png"))
    assert code == 2 and "[fast]" in err


def test_viewer_install_hint_keeps_the_extra(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "starlette", None)  # import starlette -> ImportError
    code, _, err = run_cli(monkeypatch, capsys, "view", "--no-browser")
    assert code == 2 and 'pip install "sparsecast[view]"' in err
