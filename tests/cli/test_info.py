"""`sparsecast info`: volume facts, occupancy for a TF, the lists of presets and indices."""

from __future__ import annotations

import sparsecast as sc
from cli_runner import run_cli


def test_info_reports_volume_facts(monkeypatch, capsys, small_volume_file):
    code, out, err = run_cli(monkeypatch, capsys, "info", str(small_volume_file), "--tf", "grayscale")
    assert code == 0, err
    assert "24 x 24 x 24" in out
    assert "float32" in out
    assert "occupancy" in out and "bricks" in out
    vol = sc.load_volume(small_volume_file)
    bricks = vol.brick_stats(8)
    tf = sc.TransferFunction.preset("grayscale", vol.value_range)
    expected = 100 * tf.classify(bricks.vmin, bricks.vmax).mean()
    assert f"{expected:.2f} %" in out


def test_info_lists_presets_and_indices(monkeypatch, capsys):
    code, out, _ = run_cli(monkeypatch, capsys, "info", "--presets")
    assert code == 0 and "bone" in out and "viridis" in out
    code, out, _ = run_cli(monkeypatch, capsys, "info", "--indices")
    assert code == 0 and "naive" in out
