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


@pytest.mark.parametrize(
    "args, start",
    [
        (["--dt", "-1"], "error: --dt: expected a positive"),
        (["--ert", "2"], "error: --ert: expected"),
        (["--tf-range", "5,1"], "error: --tf-range (value_range): expected finite lo <= hi, got (5.0, 1.0)"),
        (["--size", "100000x100000"], "error: --size (width): expected"),
        (["--background", "1,2"], "error: --background: expected"),
    ],
)
def test_library_checks_are_named_by_their_option(monkeypatch, capsys, tmp_path, small_volume_file, args, start):
    """Values the library checks come back under the option the user typed, not the
    library's parameter alone (``value_range`` is ``--tf-range`` on the command line)."""
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), *args,
                           "-o", str(tmp_path / "x.png"))
    assert code == 2
    assert err.strip().startswith(start), err
    assert not (tmp_path / "x.png").exists()


def test_cli_message_renames_only_parameter_checks():
    from sparsecast.cli.app import cli_message
    from sparsecast.errors import FileFormatError, ParameterError

    assert cli_message(ParameterError("dt: expected x, got 'dt: y'")) == "--dt: expected x, got 'dt: y'"
    assert cli_message(ParameterError("tf.json: value_range: missing")) == "tf.json: value_range: missing"
    assert cli_message(FileFormatError("width: a file named so")) == "width: a file named so"
    assert cli_message(ParameterError("no colon here")) == "no colon here"
