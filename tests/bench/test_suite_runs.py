"""Benchmark runs: suites as data, the case plan, resuming, sections, peers (no timing asserted)."""

from __future__ import annotations

import importlib.machinery
import json
import sys
import types

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.bench.config import BenchConfig
from sparsecast.bench.harness import run_benchmarks
from sparsecast.bench.progress import Progress, ResultStore, case_key
from sparsecast.bench.suites import SUITES, get_suite, orbit_views, view_name
from sparsecast.errors import FileFormatError, ParameterError


def test_orbit_views_turn_around_three_axes():
    views = orbit_views(4)
    angles = (22.5, 112.5, 202.5, 292.5)
    assert views == [(a, 0.0) for a in angles] + [(0.0, e) for e in angles] + [(90.0, e) for e in angles]
    vol = sc.Volume(np.zeros((5, 5, 5), np.float32))
    eyes = np.array([sc.Camera.orbit(vol, *v).eye for v in views]) - vol.center
    # around z (eye in the x-y plane), around x (y-z plane), around y (x-z plane)
    assert np.allclose(eyes[:4, 2], 0) and np.allclose(eyes[4:8, 0], 0) and np.allclose(eyes[8:, 1], 0)
    for n in (1, 2, 3, 4, 5, 8, 180):  # no two views at the same eye position
        eyes = np.array([sc.Camera.orbit(vol, *v).eye for v in orbit_views(n)])
        assert len({tuple(np.round(e, 6)) for e in eyes}) == len(eyes)
    assert len(orbit_views(2)) == 6 and len(orbit_views(180)) == 540  # the papers' 2-degree steps
    with pytest.raises(ParameterError):
        orbit_views(0)


def test_suites_cover_the_issue():
    paper = get_suite("paper")
    assert {(512, 512), (1024, 1024)} == set(paper.sizes)
    assert {"demo-128", "demo", "demo-512"} <= set(paper.dataset_names())
    assert paper.methods is None  # every registered index, discovered at run time
    specs = paper.method_specs()
    assert set(sc.available_indices()) <= set(specs)
    if "bih" in specs:  # and the BIH's approximate modes
        assert {"bih:mode=single-sample", "bih:mode=multi-sample"} <= set(specs)
    assert SUITES["quick"].method_specs() == sc.available_indices()
    assert paper.dense_tf and set(paper.peers) == {"vtk", "yt", "pyvista"} and set(paper.sections) == {"bih", "surface"}
    assert SUITES["quick"].dataset_names() == [n for n, d in sc.bench.DATASETS.items() if d.default]
    sweep = get_suite("sweep").dataset_names()
    assert len(sweep) == 10 and all(sc.bench.DATASETS[n].name == n for n in sweep)
    with pytest.raises(ParameterError, match="nope"):
        get_suite("nope")


def _keys(records):
    return [case_key(r) for r in records if r["phase"] not in ("skipped",)]


def test_run_plan_and_ratios(tiny_config):
    records = run_benchmarks(tiny_config)
    keys = _keys(records)
    assert len(keys) == len(set(keys))
    renders = [r for r in records if r["phase"] == "render"]
    # 2 TFs x 2 methods x 2 sizes x 2 views
    assert len(renders) == 16
    assert {(r["width"], r["height"]) for r in renders} == {(16, 16), (12, 8)}
    assert {r["view"] for r in renders} == {view_name((30.0, 20.0)), view_name((0.0, 90.0))}
    for r in renders:
        assert r["exact"] is True and r["samples_nonempty"] <= r["samples"]
        assert r["samples_vs_oracle"] == pytest.approx(r["samples"] / r["samples_nonempty"])
        if r["method"] == "naive":
            assert r["speedup_vs_naive"] == pytest.approx(1.0)
    # ESS takes fewer samples than naive on the sparse TF, the same on the dense one.
    for size in ((16, 16), (12, 8)):
        def samples(method, tf):
            return sum(r["samples"] for r in renders if r["method"] == method and r["tf"] == tf
                       and (r["width"], r["height"]) == size)
        assert samples("grid-pc", "default") < samples("naive", "default")
        assert samples("grid-pc", "dense") == samples("naive", "dense")


class _StopAfter(Progress):
    """Raises KeyboardInterrupt once ``n`` cases are done (a Ctrl-C mid-run)."""

    def __init__(self, n: int) -> None:
        super().__init__(0)
        self.n = n

    def advance(self, n: int = 1) -> None:
        super().advance(n)
        if self._session_done >= self.n:
            raise KeyboardInterrupt


def test_interrupted_run_resumes_without_losing_or_repeating_cases(tiny_config, tmp_path):
    journal = tmp_path / "run.jsonl"
    with pytest.raises(KeyboardInterrupt):
        run_benchmarks(tiny_config, progress=_StopAfter(9), store=ResultStore(journal))
    kept = [json.loads(line) for line in journal.read_text().splitlines()]
    assert len(kept) == 9
    with open(journal, "a") as f:
        f.write('{"dataset": "tiny", "pha')  # a line cut short by the kill

    progress = Progress(0)
    store = ResultStore(journal)
    assert store.resumed == 9
    records = run_benchmarks(tiny_config, progress=progress, store=store)
    keys = _keys(records)
    assert len(keys) == len(set(keys))  # nothing measured twice
    assert sum(r["phase"] == "render" for r in records) == 16  # nothing lost
    # The finished cases were kept as measured, not re-measured.
    by_key = {case_key(r): r for r in records}
    for old in kept:
        assert by_key[case_key(old)]["ms"] == old["ms"]
    assert progress.done_count == progress.total == len(keys)

    # A third run finds everything done and measures nothing.
    again = ResultStore(journal)
    n_lines = len(journal.read_text().splitlines())
    run_benchmarks(tiny_config, store=again)
    assert len(journal.read_text().splitlines()) == n_lines


def test_journal_with_garbage_in_the_middle_is_an_error(tmp_path):
    journal = tmp_path / "bad.jsonl"
    journal.write_text('not json\n{"phase": "load"}\n')
    with pytest.raises(FileFormatError, match="line 1"):
        ResultStore(journal)
    assert ResultStore(journal, fresh=True).records == []


@pytest.fixture
def fake_section(monkeypatch):
    """A section module ``sparsecast.bench.fakesec`` counting its runs."""
    module = types.ModuleType("sparsecast.bench.fakesec")
    module.__spec__ = importlib.machinery.ModuleSpec("sparsecast.bench.fakesec", None)
    module.calls = []

    def run(datasets, *, width, height, repeat, warmup, record):
        module.calls.append((datasets, width, height, repeat, warmup))
        record(dataset="mesh", method="rbvh", phase="render", ms=1.5, psnr=31.0, nodes=7)
        record(dataset="mesh", method="bvh", phase="build", ms=0.5, bytes=64)

    module.run = run
    monkeypatch.setitem(sys.modules, "sparsecast.bench.fakesec", module)
    return module


def test_sections_are_recorded_once_and_missing_ones_skipped(tiny_dataset, fake_section, tmp_path):
    cfg = BenchConfig(datasets=[], methods=["naive"], sizes=[(20, 10)], repeat=2, warmup=0, irt=False,
                      sections=["fakesec", "notthere"])
    store = ResultStore(tmp_path / "s.jsonl")
    records = run_benchmarks(cfg, store=store)
    assert fake_section.calls == [(None, 20, 10, 2, 1)]
    sec = [r for r in records if r.get("section") == "fakesec"]
    assert [(r["method"], r["phase"]) for r in sec] == [("rbvh", "render"), ("bvh", "build")]
    assert sec[0]["psnr"] == 31.0 and sec[0]["machine"]["cores"]
    skipped = [r for r in records if r["phase"] == "skipped"]
    assert [r["method"] for r in skipped] == ["notthere"] and "not there" in skipped[0]["reason"]
    # Resumed: the finished section is not run again.
    resumed = ResultStore(tmp_path / "s.jsonl")
    run_benchmarks(cfg, store=resumed)
    assert len(fake_section.calls) == 1
    # Its records neither stand for the main suite's cases nor join its tables.
    assert not resumed.done(dataset="mesh", method="rbvh", phase="render")
    from sparsecast.bench.summary import render_rows

    assert render_rows(records) == []


def test_dataset_names_a_section_knows_reach_it_and_make_their_own_case(tiny_dataset, fake_section, tmp_path):
    fake_section.DATASET_NAMES = ("mesh-a", "mesh-b")
    cfg = BenchConfig(datasets=[tiny_dataset, "mesh-b"], methods=["naive"], sizes=[(8, 8)], views=[(0.0, 0.0)],
                      repeat=1, warmup=0, dense_tf=False, irt=False, sections=["fakesec"])
    assert cfg.route_datasets() == []
    assert cfg.datasets == [tiny_dataset] and cfg.section_datasets == ["mesh-b"]
    journal = tmp_path / "s.jsonl"
    records = run_benchmarks(cfg, store=ResultStore(journal))
    assert fake_section.calls == [(["mesh-b"], 8, 8, 1, 1)]
    assert any(r["phase"] == "render" and r["dataset"] == tiny_dataset for r in records)
    # The same section on other data in the same journal runs; on the same data it resumes.
    other = BenchConfig(datasets=["mesh-a"], methods=["naive"], sizes=[(8, 8)], repeat=1, warmup=0,
                        irt=False, sections=["fakesec"])
    assert other.route_datasets() == []
    run_benchmarks(other, store=ResultStore(journal))
    assert [c[0] for c in fake_section.calls] == [["mesh-b"], ["mesh-a"]]
    run_benchmarks(other, store=ResultStore(journal))
    assert len(fake_section.calls) == 2
    # A name no one knows is handed back for the caller's error.
    bad = BenchConfig(datasets=["nosuch", "mesh-a"], sections=["fakesec"])
    assert bad.route_datasets() == ["nosuch"] and bad.section_datasets == ["mesh-a"]


def test_run_benchmarks_routes_section_names_itself(tiny_dataset, fake_section):
    """A config built in Python (no CLI) may name a section's dataset or an unknown one:
    the first reaches the section, the second is a skip note, and the caller's config
    is left as it was."""
    fake_section.DATASET_NAMES = ("mesh-a",)
    cfg = BenchConfig(datasets=["mesh-a", "nosuch"], methods=["naive"], sizes=[(8, 8)], repeat=1, warmup=0,
                      irt=False, sections=["fakesec"])
    records = run_benchmarks(cfg)
    assert fake_section.calls == [(["mesh-a"], 8, 8, 1, 1)]
    (note,) = [r for r in records if r["phase"] == "skipped"]
    assert note["method"] == "nosuch" and "unknown dataset" in note["reason"]
    assert cfg.datasets == ["mesh-a", "nosuch"] and cfg.section_datasets == []


def test_a_failing_section_is_noted_and_the_run_goes_on(tiny_dataset, fake_section):
    def boom(*args, **kwargs):
        raise RuntimeError("kernel exploded")

    fake_section.run = boom
    cfg = BenchConfig(datasets=[tiny_dataset], methods=["naive"], sizes=[(8, 8)], views=[(0.0, 0.0)],
                      repeat=1, warmup=0, dense_tf=False, irt=False, sections=["fakesec"])
    records = run_benchmarks(cfg)
    assert any(r["phase"] == "render" for r in records)
    (note,) = [r for r in records if r["phase"] == "skipped"]
    assert "kernel exploded" in note["reason"]


@pytest.mark.parametrize("peer", ["vtk", "yt", "pyvista"])
def test_peer_renders_the_same_case(peer, tiny_dataset, tmp_path):
    from sparsecast.bench.peers import PeerUnavailable, load_peer

    try:  # not installed, or (pyvista) no off-screen OpenGL context here
        load_peer(peer)
    except PeerUnavailable as exc:
        pytest.skip(str(exc))
    cfg = BenchConfig(datasets=[tiny_dataset], methods=["naive", "grid-pc"], sizes=[(24, 16)],
                      views=[(30.0, 20.0), (90.0, 45.0), (0.0, 0.0)], repeat=1, warmup=0, dense_tf=True,
                      irt=False, peers=[peer], peer_views=2, images_dir=tmp_path / "img")
    records = run_benchmarks(cfg)
    peer_recs = [r for r in records if r["method"] == peer]
    # the first peer_views views, with the sparse and the dense TF (zeros are not empty there)
    assert [(r["tf"], r["view"]) for r in peer_recs] == [
        ("default", "az30_el20"), ("default", "az90_el45"), ("dense", "az30_el20"), ("dense", "az90_el45")]
    for r in peer_recs:
        assert r["peer"] and r["ms"] > 0 and r["ratio_to_best"] > 0 and r["cores_busy"] >= 0
        # The same volume, camera, step and TF: close to our image (a wrong axis order,
        # camera or opacity scale drops this below ~20 dB).
        assert r["psnr_vs_naive"] > 30.0, r
    saved = sorted(p.name for p in (tmp_path / "img").iterdir())
    assert saved == sorted(f"tiny_{tf}_24x16_az30_el20_{who}.png" for tf in ("default", "dense")
                           for who in (peer, "sparsecast"))
    from sparsecast.bench.plots import write_plots

    assert "peer_images.png" in [p.name for p in write_plots(records, tmp_path / "figs")]


def test_missing_peer_is_skipped_with_the_reason(tiny_dataset, monkeypatch):
    from sparsecast.bench.peers import vtk_peer

    monkeypatch.setattr(vtk_peer, "unavailable_reason", lambda: "vtk is not installed (test)")
    cfg = BenchConfig(datasets=[tiny_dataset], methods=["naive"], sizes=[(8, 8)], views=[(0.0, 0.0)],
                      repeat=1, warmup=0, dense_tf=False, irt=False, peers=["vtk"])
    records = run_benchmarks(cfg)
    (note,) = [r for r in records if r["phase"] == "skipped"]
    assert note["method"] == "vtk" and "not installed" in note["reason"]
    assert not any(r["method"] == "vtk" and r["phase"] == "render" for r in records)


def test_dense_tf_and_approximate_modes_on_fewer_views(tiny_config):
    if "bih" not in sc.available_indices():
        pytest.skip("no BIH index registered")
    tiny_config.methods = ["naive", "bih:mode=single-sample"]
    tiny_config.sizes = [(16, 16)]
    tiny_config.dense_views = 1
    records = run_benchmarks(tiny_config)
    renders = [r for r in records if r["phase"] == "render"]
    assert {r["view"] for r in renders if r["tf"] == "dense"} == {"az30_el20"}
    assert len({r["view"] for r in renders if r["tf"] == "default"}) == 2
    approx = [r for r in renders if r["method"] == "bih:mode=single-sample"]
    assert approx and all(r["exact"] is False and 0 < r["psnr_vs_naive"] for r in approx)
    assert all("psnr_vs_naive" not in r for r in renders if r["method"] == "naive")


def test_progress_counts_and_eta_and_logs_without_a_terminal():
    from rich.console import Console
    import io

    buf = io.StringIO()
    progress = Progress(10, 4, console=Console(file=buf, force_terminal=False), label="t")
    assert progress.eta_s() is None  # nothing measured in this session yet
    progress.say("first")
    progress.advance(2)
    assert progress.done_count == 6 and progress.eta_s() >= 0.0
    assert "t: 4/10 cases, ETA --  first" in buf.getvalue()  # a plain line for a log file
    progress.close()
