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
        (["--mode", "iso", "--iso", "nan"], "error: --iso: expected 1 to 8 finite isovalues"),
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


@pytest.mark.parametrize(
    "args, start, typed",
    [
        (["bench", "--views", "x"], "error: --views: ", "'x'"),
        (["bench", "--dense-views", "two"], "error: --dense-views: ", "'two'"),
        (["render", "--zoom=abc"], "error: --zoom: ", "'abc'"),
        (["render", "--azimuth", "north"], "error: --azimuth: ", "'north'"),
        (["render", "--iso", "0.3", "--iso", "q"], "error: --iso: ", "'q'"),
        (["view", "--port", "http"], "error: --port: ", "'http'"),
        (["convert", "a.npy", "b.zarr", "--chunks", "1.5"], "error: --chunks: ", "'1.5'"),
        (["render-mesh", "m.ply", "--splits", "[v2]"], "error: --splits: ", "'[v2]'"),
    ],
)
def test_values_typer_cannot_convert_are_one_line(monkeypatch, capsys, tmp_path, args, start, typed):
    """Integer and number options typer converts itself answered with its boxed usage
    block, whose reason does not show the value; now one ``error:`` line like the rest."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(monkeypatch, capsys, *args)
    assert code == 2 and not out
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(start), err
    assert typed in lines[0] and f"see 'sparsecast {args[0]} --help'" in lines[0]
    assert "╭" not in err and "Usage:" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "args, says, command",
    [
        (["render", "--fooo"], "No such option: --fooo", "render"),
        (["render-mesh"], "Missing argument", "render-mesh"),
        (["render", "a.npy", "b.npy"], "unexpected extra argument", "render"),
        (["render", "--zoom"], "'--zoom' requires an argument", "render"),
        (["bench", "--compare", "a.json"], "'--compare' requires 2 arguments", "bench"),
        (["no-such-command"], "No such command 'no-such-command'", ""),
    ],
)
def test_usage_errors_are_one_line_naming_the_help(monkeypatch, capsys, tmp_path, args, says, command):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(monkeypatch, capsys, *args)
    assert code == 2 and not out
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert says in lines[0]
    assert lines[0].endswith(f"(see 'sparsecast{' ' + command if command else ''} --help')")


def test_bare_command_shows_the_help(monkeypatch, capsys):
    code, out, err = run_cli(monkeypatch, capsys)
    assert code == 2 and not err
    assert "Usage: sparsecast" in out and "render" in out


def test_help_exits_zero(monkeypatch, capsys):
    code, out, err = run_cli(monkeypatch, capsys, "render", "--help")
    assert code == 0 and "--zoom" in out and not err


@pytest.mark.parametrize(
    "args, start",
    [
        (["bench", "--peer-views", "-1"], "error: --peer-views: expected an integer >= 0, got -1"),
        (["bench", "--dense-views", "-2"], "error: --dense-views: expected an integer >= 0, got -2"),
        (["bench", "--dt", "-1"], "error: --dt: expected a positive world-space step, got -1"),
        (["info", "--brick-size", "-3"], "error: --brick-size: expected an integer >= 1, got -3"),
    ],
)
def test_counts_and_steps_are_checked_before_any_work(monkeypatch, capsys, tmp_path, args, start):
    """A negative view count sliced views off the end and ran a benchmark; --dt failed only
    once the first volume had loaded; --brick-size was named by its library parameter."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(monkeypatch, capsys, *args)
    assert code == 2 and not out
    assert err.strip() == err.strip().splitlines()[0] and err.startswith(start), err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("option, value", [("--chunks", "0"), ("--clevel", "12")])
def test_convert_checks_are_named_by_their_option(monkeypatch, capsys, tmp_path, small_volume_file, option, value):
    code, _, err = run_cli(monkeypatch, capsys, "convert", str(small_volume_file), str(tmp_path / "o.zarr"),
                           option, value)
    assert code == 2
    assert err.startswith(f"error: {option}: expected an integer"), err
    assert not (tmp_path / "o.zarr").exists()


def test_an_interrupted_bench_exits_130(monkeypatch, capsys, tmp_path):
    """typer.Exit(code) from a command still sets the process status."""
    import sparsecast.bench

    def interrupted(*_args, **_kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(sparsecast.bench, "run_benchmarks", interrupted)
    code, _, err = run_cli(monkeypatch, capsys, "bench", "-d", "demo", "-m", "naive",
                           "--json", str(tmp_path / "r.json"))
    assert code == 130
    assert "interrupted" in err and (tmp_path / "r.json").exists()
