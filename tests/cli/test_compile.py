"""``sparsecast compile``: the plan, bad options, and a real run into a fresh kernel cache."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from cli_runner import run_cli
from sparsecast import available_indices, kernel_cache
from sparsecast.warmup import APPROXIMATE_MODES, DEFAULT_DTYPES, GROUPS, plan


def test_full_plan_covers_every_index_dtype_and_group():
    steps = plan()
    labels = [s.label for s in steps]
    assert len(labels) == len(set(labels))
    assert [g for g in GROUPS if any(s.group == g for s in steps)] == list(GROUPS)
    specs = available_indices() + list(APPROXIMATE_MODES)
    for dtype in DEFAULT_DTYPES:
        assert f"volume {dtype}: brick statistics" in labels
        for spec in specs:
            assert f"volume {dtype} {spec}: build, frame" in labels
    volume = [s for s in steps if s.group == "volume"]
    assert len(volume) == len(DEFAULT_DTYPES) * (1 + len(specs))
    assert {s.label for s in plan(dtypes="all") if s.label.endswith("brick statistics")} == {
        f"volume {d}: brick statistics" for d in ("uint8", "uint16", "int16", "float32", "float64")}


def test_plan_subsets():
    steps = plan(dtypes=["float32"], indices=["grid-pc:cell=8"], groups=["volume"])
    assert [s.label for s in steps] == ["volume float32: brick statistics", "volume float32 grid-pc:cell=8: build, frame"]
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
])
def test_bad_options_are_one_error(monkeypatch, capsys, args, option, found):
    code, out, err = run_cli(monkeypatch, capsys, "compile", *args)
    assert code == 2 and out == ""
    assert err.startswith(f"error: {option}: ") and found in err and len(err.strip().splitlines()) == 1


def _compile(cache: Path, *args: str) -> str:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "SPARSECAST_CACHE_DIR")}
    env["SPARSECAST_CACHE_DIR"] = str(cache)
    res = subprocess.run([sys.executable, "-m", "sparsecast", "compile", *args], env=env,
                         capture_output=True, text=True, timeout=240)
    assert res.returncode == 0, res.stderr
    return res.stdout


def test_compile_fills_a_fresh_cache_and_a_second_run_compiles_nothing(tmp_path):
    """A subset (one dtype, one index: two steps) in a subprocess with its own cache folder."""
    args = ("--only", "volume", "--dtype", "uint8", "--index", "naive")
    first = _compile(tmp_path, *args)
    m = re.search(r"compiled 2 kernel groups in ([\d.]+) s \(Numba compiling ([\d.]+) s", first)
    assert m, first
    assert float(m.group(2)) > 0
    folder = tmp_path / f"kernels-{kernel_cache.source_hash()}"
    assert f"cache {folder}" in first
    cached = {p.name.split("-")[0] for p in folder.rglob("*.nbi")}
    # The driver (specialised for the naive record and uint8) and the brick kernel are cached.
    assert {"driver.dvr_tile", "driver.dvr_tiles", "bricks.brick_minmax"} <= cached, sorted(cached)
    second = _compile(tmp_path, *args)
    m2 = re.search(r"Numba compiling ([\d.]+) s", second)
    assert m2 and float(m2.group(1)) == 0.0, second  # everything came from the cache
