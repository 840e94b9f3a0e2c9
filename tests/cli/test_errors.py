"""Bad input to any command: one line on stderr starting 'error:', exit status 2, no traceback, no output file."""

from __future__ import annotations

import pytest

from cli_runner import run_cli


@pytest.mark.parametrize(
    "args, names",
    [
        (["render", "--size", "0x5"], "width"),
        (["render", "--size", "abc"], "--size"),
        (["render", "--size", "100000x100000"], "width"),
        (["render", "--tf", "no-such-preset", "--size", "8x8"], "preset"),
        (["render", "--index", "no-such-index", "--size", "8x8"], "index"),
        (["render", "--index", "bih:mode", "--size", "8x8"], "bih:mode"),
        (["render", "--index", "bih:mode=sideways", "--size", "8x8"], "mode"),
        (["render", "--dt", "-1", "--size", "8x8"], "dt"),
        (["render", "--background", "mauve", "--size", "8x8"], "background"),
        (["render", "does-not-exist.nrrd"], "does-not-exist.nrrd"),
        (["info", "volume.xyz"], "volume.xyz"),
        (["bench", "--repeat", "0"], "--repeat"),
        (["bench", "--warmup", "-1"], "--warmup"),
        (["bench", "--views", "0"], "--views"),
        (["render-mesh", "mesh.ply", "--mode", "xray"], "--mode"),
        (["render-mesh", "mesh.ply", "--index", "kdtree"], "--index"),
    ],
)
def test_bad_input_is_one_clear_line(monkeypatch, capsys, tmp_path, args, names):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(monkeypatch, capsys, *args)
    assert code == 2
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error:")
    assert names in lines[0]
    assert "Traceback" not in err
    assert not (tmp_path / "sparsecast.png").exists()
