"""``sparsecast compile``: the plan, bad options, and a real run into a fresh kernel cache."""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cli_runner import run_cli
from sparsecast import available_indices, kernel_cache
from sparsecast.index.registry import index_class
from sparsecast import ParameterError, SparsecastError, compile_kernels
from sparsecast.warmup import APPROXIMATE_MODES, AUTO_INDICES, DEFAULT_DTYPES, GROUPS, LABEL_INDICES, _lanes, plan


def test_full_plan_covers_every_index_dtype_and_group():
    steps = plan()
    labels = [s.label for s in steps]
    assert len(labels) == len(set(labels))
    assert [g for g in GROUPS if any(s.group == g for s in steps)] == list(GROUPS)
    # The package's own indices: one a test registers (test-bbox) renders uncached anyway.
    own = [n for n in available_indices() if index_class(n).__module__.startswith("sparsecast.")]
    assert not any(n not in own and f" {n}: " in label for n in available_indices() for label in labels)
    specs = own + list(APPROXIMATE_MODES)
    for dtype in DEFAULT_DTYPES:
        assert f"volume {dtype}: brick statistics" in labels
        for spec in specs:
            assert f"volume {dtype} {spec}: build, frame" in labels
        for spec in AUTO_INDICES:  # the iso modes and bricked storage: their own specialisations
            assert f"volume {dtype} iso {spec}: iso, iso+dvr frames" in labels
            assert f"volume {dtype} bricked {spec}: frame" in labels
        if dtype.startswith(("uint", "int")):
            for spec in LABEL_INDICES:
                assert f"volume {dtype} labels {spec}: build, frames" in labels
    volume = [s for s in steps if s.group == "volume"]
    integer = [d for d in DEFAULT_DTYPES if d.startswith(("uint", "int"))]
    assert len(volume) == (len(DEFAULT_DTYPES) * (1 + len(specs) + 2 * len(AUTO_INDICES))
                           + len(integer) * len(LABEL_INDICES))
    assert {s.label for s in plan(dtypes="all") if s.label.endswith("brick statistics")} == {
        f"volume {d}: brick statistics" for d in ("uint8", "uint16", "int16", "float32", "float64")}


def test_plan_subsets():
    steps = plan(dtypes=["float32"], indices=["grid-pc:cell=8"], groups=["volume"])
    assert [s.label for s in steps] == ["volume float32: brick statistics", "volume float32 grid-pc:cell=8: build, frame",
                                        "volume float32 iso grid-pc:cell=8: iso, iso+dvr frames",
                                        "volume float32 bricked grid-pc:cell=8: frame"]
    # Iso, bricked and (integer dtypes) label TFs for the exact indices asked for only.
    steps = plan(dtypes=["uint16"], indices=["lbvh", "bih:mode=multi-sample"], groups=["volume"])
    assert [s.label for s in steps] == ["volume uint16: brick statistics", "volume uint16 lbvh: build, frame",
                                        "volume uint16 bih:mode=multi-sample: build, frame",
                                        "volume uint16 iso lbvh: iso, iso+dvr frames",
                                        "volume uint16 bricked lbvh: frame",
                                        "volume uint16 labels lbvh: build, frames"]
    assert {s.group for s in plan(groups=["surface", "particles"])} == {"surface", "particles"}


def test_list_prints_the_plan_without_compiling(monkeypatch, capsys):
    code, out, err = run_cli(monkeypatch, capsys, "compile", "--list", "--only", "particles")
    assert code == 0, err
    assert "particles: BIH build, frame" in out and "1 steps" in out
    assert str(kernel_cache.cache_dir() or "Numba default") in out


@pytest.mark.parametrize("args, option, found", [
    (["--dtype", "int8"], "--dtype", "'int8'"),
    (["--only", "vol"], "--only", "'vol'"),
    (["--index", "nope"], "--index", "'nope'"),
    (["--index", "grid-pc:cel=8"], "--index", "'cel'"),
    (["--index", "auto"], "--index", "'auto'"),
    (["--jobs", "0"], "--jobs", "got '0'"),
    (["--jobs", "two"], "--jobs", "'two'"),
])
def test_bad_options_are_one_error(monkeypatch, capsys, args, option, found):
    code, out, err = run_cli(monkeypatch, capsys, "compile", *args)
    assert code == 2 and out == ""
    assert err.startswith(f"error: {option}: ") and found in err and len(err.strip().splitlines()) == 1


def _sparsecast(cache: Path, *args: str) -> str:
    """stdout of ``python -m sparsecast ARGS`` in a subprocess using the kernel cache under ``cache``."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "SPARSECAST_CACHE_DIR")}
    env["SPARSECAST_CACHE_DIR"] = str(cache)
    res = subprocess.run([sys.executable, "-m", "sparsecast", *args], env=env,
                         capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr
    return res.stdout


def test_compile_fills_a_fresh_cache_and_a_second_run_compiles_nothing(tmp_path):
    """A subset (one dtype, one index: four volume steps; and particles) in a subprocess with
    its own cache folder, the two lanes in two processes of their own."""
    args = ("compile", "--only", "volume", "--only", "particles", "--dtype", "float32", "--index", "naive",
            "--jobs", "2")
    cache = tmp_path / "cache"
    first = _sparsecast(cache, *args)
    m = re.search(r"compiled 5 kernel groups in ([\d.]+) s \(Numba compiling ([\d.]+) s in 2 processes", first)
    assert m, first
    assert float(m.group(2)) > 0
    folder = cache / f"kernels-{kernel_cache.source_hash()}"
    assert f"cache {folder}" in first
    cached = {p.name.split("-")[0] for p in folder.rglob("*.nbi")}
    # The driver (specialised for the naive record and float32) and the brick kernel are cached,
    # and the particle renderer, compiled by the other process, in the same folder.
    assert {"driver.dvr_tiles", "driver.new_scratch", "windows.window_minmax",
            "particles._particle_tiles"} <= cached, sorted(cached)
    second = _sparsecast(cache, *args[:-2], "--jobs", "1")  # one process: loads what the two compiled
    m2 = re.search(r"Numba compiling ([\d.]+) s;", second)
    assert m2 and float(m2.group(1)) == 0.0, second  # everything came from the cache
    # What compile compiled is what render runs: a float32 volume with that index compiles nothing.
    vol = tmp_path / "vol.npy"
    np.save(vol, np.random.default_rng(1).random((20, 18, 16)).astype(np.float32))
    line = _sparsecast(cache, "render", str(vol), "--index", "naive", "--size", "16x16", "-o", str(tmp_path / "a.png"))
    assert "wrote" in line and not re.search(r"compile \d+ ms", line), line
    # ... and so does an isosurface of it.
    line = _sparsecast(cache, "render", str(vol), "--index", "naive", "--size", "16x16", "--mode", "iso",
                       "--iso", "0.5", "-o", str(tmp_path / "b.png"))
    assert "wrote" in line and not re.search(r"compile \d+ ms", line), line


@pytest.mark.parametrize("terminal", [True, False])
def test_commands_at_a_terminal_announce_their_first_compile(monkeypatch, capsys, terminal):
    """A first render compiles for a minute: at a terminal the command says why, once;
    `sparsecast compile` withdraws the note (its progress bar says so); logs get none."""
    from sparsecast import kernel_cache
    cli_app = importlib.import_module("sparsecast.cli.app")  # (sparsecast.cli.app is also the Typer app)

    notes = []
    monkeypatch.setattr(kernel_cache, "announce_first_compile", notes.append)
    monkeypatch.setattr(cli_app.err, "_force_terminal", terminal)
    code, out, err = run_cli(monkeypatch, capsys, "compile", "--list", "--only", "particles")
    assert code == 0, err
    if not terminal:
        assert notes == [None]  # only compile's withdrawal: nothing was installed
        return
    note, withdrawn = notes
    assert withdrawn is None
    note()
    assert cli_app.FIRST_COMPILE_NOTE in capsys.readouterr().err


def test_lanes_keep_each_dtype_and_group_in_plan_order():
    steps = plan(dtypes=["uint8", "float32"], indices=["naive", "grid-pc"], groups=["volume", "surface", "particles"])
    lanes = _lanes(steps)
    assert sorted(i for lane in lanes for i in lane) == list(range(len(steps)))
    assert [steps[lane[0]].label for lane in lanes] == [
        "volume uint8: brick statistics", "volume float32: brick statistics", "surface BVH: build",
        "particles: BIH build, frame"]
    for lane in lanes:
        assert lane == sorted(lane)
        assert len({steps[i].lane or steps[i].group for i in lane}) == 1
    assert all(" uint8" in steps[i].label for i in lanes[0]) and all(" float32" in steps[i].label for i in lanes[1])


#: two lanes of one short step each (brick statistics of two dtypes): the parallel path, cheaply
_TWO_LANES = dict(dtypes=["uint8", "float32"], indices=[], groups=["volume"])


def test_parallel_run_reports_every_step_in_plan_order_with_progress():
    """Two lanes in two spawned processes, on this session's kernel cache."""
    seen = []
    report = compile_kernels(**_TWO_LANES, progress=lambda done, total, label: seen.append((done, total, label)),
                             jobs=2)
    labels = [s.label for s in plan(**_TWO_LANES)]
    assert labels == ["volume uint8: brick statistics", "volume float32: brick statistics"]
    assert report.jobs == 2 and [s[0] for s in report.steps] == labels
    assert all(ms > 0 for _, ms, _ in report.steps)
    assert report.total_ms >= max(ms for _, ms, _ in report.steps) and report.wall_ms > 0
    assert sorted(label for _, _, label in seen[:-1]) == sorted(labels)  # each step, as it started
    assert seen[-1] == (len(labels), len(labels), "")
    assert all(done < len(labels) for done, _, _ in seen[:-1])
    assert compile_kernels(**_TWO_LANES, jobs=5).jobs == 2  # no more processes than lanes


def test_a_compile_process_that_dies_is_one_error():
    """Killed from outside (the OOM killer, say): one error naming what to do, not a traceback."""
    import multiprocessing
    import signal

    killed = []

    def progress(done, total, label):
        if label and not killed:  # a step has started: its process is busy with it
            for child in multiprocessing.active_children():
                os.kill(child.pid, signal.SIGKILL)
                killed.append(child.pid)

    # Lanes of several steps (a dtype's naive index), so that a lane is still running when
    # its first step's start comes through; killed at once, they compile next to nothing.
    with pytest.raises(SparsecastError, match=r"^jobs: a compile process died .* fewer jobs"):
        compile_kernels(dtypes=["uint8", "float32"], indices=["naive"], groups=["volume"], progress=progress, jobs=2)
    assert killed


def test_jobs_must_be_a_positive_integer():
    with pytest.raises(ParameterError, match="jobs"):
        compile_kernels(groups=["particles"], jobs=0)


def test_an_index_registered_here_compiles_here(monkeypatch):
    """A fresh process would not know it: jobs > 1 falls back to this process."""
    from sparsecast.warmup import _spawnable

    assert _spawnable(None) and _spawnable(["naive", "bih:mode=multi-sample"])
    monkeypatch.setattr(index_class("naive"), "__module__", "someone.elses")
    assert not _spawnable(["naive"])


def _fake_clock(monkeypatch, module: str, seconds: list[float]) -> None:
    """Make ``module``'s compile clock read ``seconds`` in turn (then the last value)."""
    values = iter(seconds)
    last = [seconds[-1]]

    def clock() -> float:
        last[0] = next(values, last[0])
        return last[0]

    monkeypatch.setattr(f"sparsecast.cli.{module}.compile_seconds", clock)


def _mesh_file(tmp_path: Path) -> Path:
    import trimesh

    from sparsecast.surface.mesh import icosphere

    path = tmp_path / "sphere.ply"
    s = icosphere(2)
    trimesh.Trimesh(s.vertices, s.faces, process=False).export(path)
    return path


@pytest.mark.parametrize("command", ["render", "info", "render-mesh"])
@pytest.mark.parametrize("compiled", [0.0, 2.5])
def test_status_line_names_compilation_apart_only_when_there_was_some(monkeypatch, capsys, tmp_path,
                                                                      small_volume_file, command, compiled):
    module = {"render": "render", "info": "info", "render-mesh": "mesh"}[command]
    _fake_clock(monkeypatch, module, [10.0, 10.0 + compiled])
    args = {"render": [str(small_volume_file), "--size", "16x16", "-o", str(tmp_path / "a.png")],
            "info": [str(small_volume_file)],
            "render-mesh": [str(_mesh_file(tmp_path)), "--size", "16x16", "-o", str(tmp_path / "m.png")]}[command]
    code, out, err = run_cli(monkeypatch, capsys, command, *args)
    assert code == 0, err
    assert re.findall(r"compile \d+ ms", out) == (["compile 2500 ms"] if compiled else []), out
