"""Benchmark outputs: --compare ratios, the Markdown report, figures and the CLI around them."""

from __future__ import annotations

import json

import pytest
from PIL import Image as PILImage

from sparsecast.bench.compare import compare_records, format_comparison
from sparsecast.bench.markdown import markdown_report
from sparsecast.bench.plots import write_plots
from sparsecast.bench.ratios import add_ratios
from sparsecast.bench.report import load_records
from sparsecast.errors import FileFormatError
from cli_runner import run_cli


def _render(ds, method, ms, *, tf="default", view="v1", size=512, samples=1000, oracle=100, **kw):
    return {"dataset": ds, "tf": tf, "method": method, "phase": "render", "view": view, "ms": ms,
            "width": size, "height": size, "samples": samples, "samples_nonempty": oracle,
            "bytes": 1024, "exact": True, **kw}


def _run(scale: float = 1.0) -> list[dict]:
    """A fake run: naive, two indices, one approximate index and a peer on two views."""
    recs = [{"dataset": "d", "phase": "load", "ms": 5.0, "dims": [8, 8, 8], "machine": {"cpu": "test cpu", "cores": 2}},
            {"dataset": "d", "tf": "default", "phase": "tf_classify", "ms": 0.1, "occupancy": 0.25}]
    for m, build in (("naive", 0.0), ("grid-pc", 2.0), ("lbvh", 3.0)):
        recs.append({"dataset": "d", "tf": "default", "method": m, "phase": "build_cold", "ms": 10 * build})
        recs.append({"dataset": "d", "tf": "default", "method": m, "phase": "rebuild", "ms": build, "bytes": 4096,
                     "index_stats": {"phases": {"classify": build / 4, "split": 3 * build / 4}}})
    for view in ("v1", "v2"):
        recs += [_render("d", "naive", 100.0 * scale, view=view, samples=1000, samples_cell_bound=150),
                 _render("d", "grid-pc", 10.0 * scale, view=view, samples=300),
                 _render("d", "lbvh", 20.0, view=view, samples=200),
                 _render("d", "bih:mode=single-sample", 5.0, view=view, samples=50, exact=False, psnr_vs_naive=33.0)]
    recs.append(_render("d", "vtk", 40.0, view="v1", samples=None, oracle=None, peer=True, exact=False,
                        psnr_vs_naive=41.0, image="img/d_vtk.png"))
    recs.append({"dataset": None, "method": "yt", "phase": "skipped", "kind": "peer", "reason": "yt is not installed"})
    add_ratios(recs)
    return recs


def test_ratios_best_index_and_peer():
    recs = _run()
    grid = [r for r in recs if r.get("method") == "grid-pc" and r["phase"] == "render"]
    assert all(r["speedup_vs_naive"] == pytest.approx(10.0) for r in grid)
    assert grid[0]["samples_vs_oracle"] == pytest.approx(3.0)
    (vtk,) = [r for r in recs if r.get("method") == "vtk"]
    # Against our fastest *exact* index (grid-pc, 10 ms), not the faster approximate one.
    assert vtk["ratio_to_best"] == pytest.approx(4.0)


def test_markdown_report_names_best_index_and_peers(tmp_path):
    text = markdown_report(_run(), suite="paper", figures=[tmp_path / "figs" / "frame_times.png"],
                           relative_to=tmp_path)
    summary = text.split("## Summary")[1].split("##")[0]
    row = next(line for line in summary.splitlines() if line.startswith("| d (8×8×8)"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    # dataset, TF, size, occupancy, best, frame ms, naive ms, x naive, work eff, cell bound, rebuild,
    # bytes, x vtk; the cell bound is the naive frames' samples in occupied cells / oracle
    assert cells[4] == "`grid-pc`" and cells[5] == "10.0" and cells[6] == "100.0"
    assert cells[7] == "10.0×" and cells[8] == "3.00" and cells[9] == "1.50" and cells[10] == "2.00"
    assert cells[12] == "4.0×"
    assert "25.0 %" in row and "test cpu" in text
    assert "## Peers on the same cases" in text and "41.0 dB" in text and "`d_vtk.png`" in text
    assert "## Approximate indices" in text and "33.0 dB" in text
    assert "- peer `yt`: yt is not installed" in text
    assert "| `grid-pc` | 20.0 | 2.00 | classify 0.500 · split 1.50 | 4.0 KiB |" in text  # per-dataset table
    assert "![frame_times](figs/frame_times.png)" in text


def test_compare_ratios_and_counts():
    old, new = _run(), _run(scale=2.0)
    new = [r for r in new if r.get("view") != "v2"] + [_render("e", "naive", 1.0)]
    section = {"dataset": "mesh", "method": "rbvh", "phase": "render", "view": [30, 20], "ms": 2.0, "section": "s"}
    old, new = old + [section], new + [{**section, "ms": 3.0}]
    cases, only_old, only_new = compare_records(old, new)
    ratio = {c.label(): c.ratio for c in cases}
    assert ratio["d default naive render 512x512 v1"] == pytest.approx(2.0)
    assert ratio["d default lbvh render 512x512 v1"] == pytest.approx(1.0)
    assert ratio["d default grid-pc rebuild"] == pytest.approx(1.0)
    assert ratio['[s] mesh rbvh render [30, 20]'] == pytest.approx(1.5)
    assert only_old == 4 and only_new == 1  # the v2 renders; the new dataset
    table = format_comparison(cases, only_old, only_new)
    assert "4 only in old" in table.caption and "slower" in table.caption


def test_cli_compare(monkeypatch, capsys, tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps(_run()))
    b.write_text(json.dumps(_run(scale=0.5)))
    code, out, err = run_cli(monkeypatch, capsys, "bench", "--compare", str(a), str(b))
    assert code == 0, err
    assert "d default naive render 512x512 v1" in out and "0.50" in out
    (tmp_path / "c.json").write_text(json.dumps([_render("zzz", "naive", 1.0)]))
    code, _, err = run_cli(monkeypatch, capsys, "bench", "--compare", str(a), str(tmp_path / "c.json"))
    assert code == 2 and "no case in common" in err
    (tmp_path / "bad.json").write_text("{")
    code, _, err = run_cli(monkeypatch, capsys, "bench", "--compare", str(a), str(tmp_path / "bad.json"))
    assert code == 2 and "bad.json" in err


def test_load_records_rejects_other_json(tmp_path):
    p = tmp_path / "x.json"
    p.write_text(json.dumps({"not": "records"}))
    with pytest.raises(FileFormatError, match="benchmark records"):
        load_records(p)


def test_build_vs_render_figure_per_volume_size(tmp_path):
    recs = []
    for ds, n in (("demo-128", 128), ("demo", 256), ("demo-512", 512)):
        recs.append({"dataset": ds, "phase": "load", "dims": [n, n, n], "ms": 1.0})
        for m, ms in (("naive", n / 2), ("grid-pc", n / 20)):
            recs.append(_render(ds, m, ms))
            recs.append({"dataset": ds, "tf": "default", "method": m, "phase": "rebuild", "ms": n / 100})
            recs.append({"dataset": ds, "tf": "default", "method": m, "phase": "build_cold", "ms": n / 10})
    recs.append(_render("demo", "vtk", 30.0, peer=True, exact=False))
    names = [p.name for p in write_plots(recs, tmp_path)]
    assert names == ["frame_times.png", "build_times.png", "build_vs_render.png"]
    with PILImage.open(tmp_path / "build_vs_render.png") as im:
        assert im.size[0] > 600 and im.size[1] > 250


def test_cli_suite_resumes_and_writes_report(monkeypatch, capsys, tmp_path, tiny_dataset):
    args = ["bench", "--suite", "quick", "-d", tiny_dataset, "-m", "naive", "-m", "grid-pc", "--size", "16x16",
            "--size", "8x8", "--views", "2", "--repeat", "1", "--warmup", "0", "--no-dense",
            "--json", str(tmp_path / "r.json"), "--report", str(tmp_path / "B.md"), "--plot", str(tmp_path / "f")]
    code, out, err = run_cli(monkeypatch, capsys, *args)
    assert code == 0, err
    assert "best index per dataset" in out and "16x16" in out  # the console headline
    records = json.loads((tmp_path / "r.json").read_text())
    renders = [r for r in records if r["phase"] == "render"]
    assert len(renders) == 2 * 2 * 6  # methods x sizes x views (2 per axis)
    assert (tmp_path / "r.jsonl").exists() and (tmp_path / "f" / "frame_times.png").exists()
    assert list((tmp_path / "images").glob("*.png"))  # images beside the records, not in the cwd
    report = (tmp_path / "B.md").read_text()
    assert f"Written by `sparsecast {' '.join(args)}`" in report
    assert "## Summary" in report and "`grid-pc`" in report and "frame_times.png" in report
    code, out, err = run_cli(monkeypatch, capsys, *args)
    assert code == 0 and "resuming" in err
    again = json.loads((tmp_path / "r.json").read_text())
    assert [r["ms"] for r in again if r["phase"] == "render"] == [r["ms"] for r in renders]


@pytest.mark.parametrize("args, message", [
    (["--suite", "nope"], "nope"),
    (["--peer", "nope"], "nope"),
    (["--views", "0"], "--views"),
    (["--size", "12x"], "--size"),
])
def test_cli_bench_option_errors(monkeypatch, capsys, args, message):
    code, _, err = run_cli(monkeypatch, capsys, "bench", *args)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_cli_ctrl_c_writes_what_is_finished(monkeypatch, capsys, tmp_path, tiny_dataset):
    from sparsecast.bench import progress as progress_module

    advance = progress_module.Progress.advance

    def interrupt_after_five(self, n=1):
        advance(self, n)
        if self._session_done >= 5:
            raise KeyboardInterrupt

    monkeypatch.setattr(progress_module.Progress, "advance", interrupt_after_five)
    code, out, err = run_cli(monkeypatch, capsys, "bench", "-d", tiny_dataset, "-m", "naive", "--size", "8x8",
                             "--repeat", "1", "--warmup", "0", "--json", str(tmp_path / "r.json"),
                             "--report", str(tmp_path / "B.md"))
    assert code == 130 and "interrupted: 5 of" in err and "run the same command again" in err
    assert len(json.loads((tmp_path / "r.json").read_text())) == 5
    assert len((tmp_path / "r.jsonl").read_text().splitlines()) == 5
    assert (tmp_path / "B.md").exists()


def test_sweep_plot_from_records(tmp_path):
    recs = []
    for k, naive_ms, grid_ms in [(1, 100.0, 5.0), (64, 100.0, 20.0), (512, 100.0, 90.0)]:
        for m, ms in (("naive", naive_ms), ("grid-pc", grid_ms)):
            recs.append({"dataset": f"fig5b-256-k{k:04d}", "tf": "default", "method": m,
                         "phase": "render", "ms": ms})
    paths = write_plots(recs, tmp_path)
    assert [p.name for p in paths] == ["sweep_fig5b-256.png"]
    assert paths[0].stat().st_size > 1000


def test_surface_table_ratios_per_cpu_second():
    from rich.console import Console

    from sparsecast.bench.report import format_surface

    def rec(method, phase, **kw):
        return {"section": "surface", "dataset": "m", "method": method, "phase": phase, **kw}

    recs = [rec("mesh", "load", triangles=1234),
            rec("bvh", "build", ms=500.0), rec("embree", "build", ms=250.0),
            rec("rbvh-Q2", "memory", mem_ratio=0.125),
            rec("bvh", "render", ms=10.0, mrays_cpu_s=4.0), rec("rbvh-Q2", "render", ms=8.0, mrays_cpu_s=6.0, psnr=37.5),
            rec("embree", "render", ms=5.0, mrays_cpu_s=8.0),
            rec("bvh", "render_diffuse", mrays_cpu_s=1.0), rec("embree", "render_diffuse", mrays_cpu_s=4.0)]
    assert format_surface([r for r in recs if r["phase"] != "render"]) is None
    console = Console(width=300, record=True)
    console.print(format_surface(recs))
    lines = {line.split("│")[3].strip(): [c.strip() for c in line.split("│")[1:-1]]
             for line in console.export_text().splitlines() if line.count("│") > 10}
    bvh, rbvh, emb = lines["bvh"], lines["rbvh-Q2"], lines["embree"]
    assert bvh[1] == "1234" and bvh[3] == "500" and emb[3] == "250"
    assert (bvh[8], bvh[9], bvh[11]) == ("1.00", "0.50", "0.25")  # x bvh, x embree, diffuse x embree
    assert (rbvh[8], rbvh[9], rbvh[12], rbvh[13]) == ("1.50", "0.75", "37.5", "0.125")
    assert rbvh[11] == ""  # no diffuse record: no ratio made up
