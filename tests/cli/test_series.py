"""``sparsecast render SERIES --time T`` and ``--all-times -o frames/%04d.png``."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from cli_runner import run_cli


@pytest.fixture
def series_dir(tmp_path):
    folder = tmp_path / "run[1]"
    folder.mkdir()
    for t in range(3):
        d = np.zeros((16, 16, 16), np.float32)
        d[4:10, 4:10, 2 + 4 * t:6 + 4 * t] = 0.5 + 0.25 * t  # a box that moves and brightens
        sc.save_volume(sc.Volume(d), folder / f"step{t}.nrrd")
    return folder


def test_all_times_writes_one_frame_per_step_like_the_api(monkeypatch, capsys, tmp_path, series_dir):
    frames = tmp_path / "frames"
    frames.mkdir()
    code, out, err = run_cli(monkeypatch, capsys, "render", str(series_dir), "--all-times", "--size", "24x24",
                             "-o", str(frames / "f%02d.png"), "--array", str(frames / "f%02d.npy"))
    assert code == 0, err
    assert "wrote 3 frames" in out and "run[1]" in out
    series = sc.load_series(series_dir)
    tf = sc.TransferFunction.preset("viridis", series.value_range)  # one TF over every step
    cam = sc.Camera.orbit(series[0], 30, 20)
    for t in range(3):
        ref = sc.render(series[t], tf, cam, 24, 24, background="black")
        np.testing.assert_allclose(np.load(frames / f"f{t:02d}.npy"), ref.rgba, atol=1e-6)
        assert (frames / f"f{t:02d}.png").is_file()
    a, b = np.load(frames / "f00.npy"), np.load(frames / "f02.npy")
    assert not np.allclose(a, b)


def test_time_renders_one_step(monkeypatch, capsys, tmp_path, series_dir):
    code, out, err = run_cli(monkeypatch, capsys, "render", str(series_dir), "--time", "-1", "--size", "16x16",
                             "-o", str(tmp_path / "last.png"))
    assert code == 0, err
    assert "step 2: step2.nrrd" in out and (tmp_path / "last.png").is_file()


@pytest.mark.parametrize("args, fragment", [
    (["--all-times", "-o", "same.png"], "pattern"),
    (["--time", "3", "-o", "x.png"], "time: expected a step in 0..2"),
    (["--time", "0", "--all-times", "-o", "f%d.png"], "pick one"),
])
def test_bad_series_options(monkeypatch, capsys, tmp_path, series_dir, args, fragment):
    args = [a if not a.endswith(".png") else str(tmp_path / a) for a in args]
    code, _, err = run_cli(monkeypatch, capsys, "render", str(series_dir), *args)
    assert code == 2 and fragment in err
    assert not list(tmp_path.glob("*.png"))


def test_time_needs_a_file(monkeypatch, capsys, tmp_path):
    code, _, err = run_cli(monkeypatch, capsys, "render", "--time", "0", "-o", str(tmp_path / "x.png"))
    assert code == 2 and "--time/--all-times" in err
