"""`sparsecast bench`: records, figures, and names checked before anything runs."""

from __future__ import annotations

import json
import re

import pytest
from PIL import Image as PILImage

import sparsecast as sc
from cli_runner import run_cli


def test_bench_writes_records(monkeypatch, capsys, tmp_path):
    path = tmp_path / "bench.json"
    code, out, err = run_cli(
        monkeypatch, capsys, "bench", "--dataset", "demo", "--size", "24x24", "--repeat", "1",
        "--warmup", "0", "--json", str(path),
    )
    assert code == 0, err
    assert "sparsecast bench" in out
    records = json.loads(path.read_text())
    phases = {r["phase"] for r in records}
    assert {"load", "brick_stats", "tf_classify", "build_cold", "rebuild", "render",
            "irt_build", "irt_query", "prefix_query"} <= phases
    assert {r["tf"] for r in records if r["phase"] == "render"} == {"default", "dense"}
    renders = [r for r in records if r["phase"] == "render"]
    assert renders and all(r["samples"] > 0 and r["ms"] > 0 for r in renders)
    for r in renders:
        assert r["samples_nonempty"] <= r["samples"]
        if r["method"] == "naive":
            assert r["speedup_vs_naive"] == pytest.approx(1.0)
    assert all(r["machine"]["cores"] for r in records)
    assert {r["dataset"] for r in records} == {"demo", "tf-table"}
    # Every exact index renders with ratios against naive from the same run.
    methods = {r["method"] for r in renders}
    assert methods == set(sc.available_indices())
    assert all(r["speedup_vs_naive"] is not None for r in renders)


def test_bench_plots(monkeypatch, capsys, tmp_path):
    code, out, err = run_cli(
        monkeypatch, capsys, "bench", "-d", "demo", "-m", "naive", "-m", "grid-pc", "--size", "16x16",
        "--repeat", "1", "--warmup", "0", "--no-dense", "--json", str(tmp_path / "b.json"),
        "--plot", str(tmp_path / "figs"),
    )
    assert code == 0, err
    for name in ("frame_times.png", "build_times.png"):
        with PILImage.open(tmp_path / "figs" / name) as im:
            assert im.size[0] > 200 and im.size[1] > 200


def test_bench_rejects_unknown_names(monkeypatch, capsys):
    code, _, err = run_cli(monkeypatch, capsys, "bench", "--dataset", "nope")
    assert code == 2 and "nope" in err
    code, _, err = run_cli(monkeypatch, capsys, "bench", "--method", "nope")
    assert code == 2 and "nope" in err
    # With the surface suite, its meshes are names too, and the error lists them.
    code, _, err = run_cli(monkeypatch, capsys, "bench", "--suite", "surface", "--dataset", "nope")
    assert code == 2 and "'nope'" in err and "dragons-7m" in err


def test_bench_surface_suite_takes_a_mesh_name(monkeypatch):
    from sparsecast.bench.config import BenchConfig
    from sparsecast.bench.suites import get_suite
    from sparsecast.cli.bench import _check_names

    cfg = BenchConfig.from_suite(get_suite("surface"), datasets=["dragon"])
    _check_names(cfg)
    assert cfg.datasets == [] and cfg.section_datasets == ["dragon"]


def test_bench_help_is_whole_at_80_columns(monkeypatch, capsys):
    """Nothing cut with an ellipsis at a narrow terminal, and the suites' durations listed."""
    from sparsecast.bench.suites import SUITES

    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.setenv("TERMINAL_WIDTH", "80")
    code, out, err = run_cli(monkeypatch, capsys, "bench", "--help")
    assert code == 0, err
    assert "…" not in out  # rich cuts a word too long for its column with an ellipsis
    flat = " ".join(line.strip(" │") for line in out.splitlines())
    flat = re.sub(r"\s+", " ", flat)
    for suite in SUITES.values():
        if suite.duration:
            assert f"{suite.name} ({suite.short}, {suite.duration})" in flat
    assert "bench-<time>.json" in flat and "records.json" in flat


def test_bench_features_suite_takes_volume_names_for_its_section_alone():
    """``--suite features -d tooth``: the features on the tooth, not every index on it too
    (the suite names no volumes of its own); with volumes of its own, a name stays theirs."""
    from sparsecast.bench.config import BenchConfig
    from sparsecast.bench.suites import get_suite
    from sparsecast.cli.bench import _check_names

    cfg = BenchConfig.from_suite(get_suite("features"), datasets=["tooth", "headsq"])
    _check_names(cfg)
    assert cfg.datasets == [] and cfg.section_datasets == ["tooth", "headsq"]
    quick = BenchConfig.from_suite(get_suite("quick"), datasets=["tooth"], sections=["features"])
    _check_names(quick)
    assert quick.datasets == ["tooth"] and quick.section_datasets == []
