"""Benchmark output: a console table, and the JSON file of records (written and read back)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..errors import FileFormatError
from .._util.atomic import atomic_path

__all__ = ["format_table", "format_summary", "format_features", "format_scale", "write_json", "load_records"]


def _fmt(v: Any, spec: str) -> str:
    if v is None:
        return ""
    try:
        return format(v, spec)
    except (TypeError, ValueError):  # e.g. a section's float where an int was expected
        return str(v)


def format_table(records: list[dict[str, Any]]):
    """A :class:`rich.table.Table` with one row per record.

    Render rows show the median frame ms of the interleaved rounds, the min-max of
    the timed runs, cores busy (CPU / wall) and cycles per sample (CPU time at the
    nominal clock over the samples taken); the raw runs are in the JSON."""
    from rich.table import Table

    table = Table(title="sparsecast bench", show_lines=False)
    for col, justify in (
        ("dataset", "left"), ("tf", "left"), ("method", "left"), ("phase", "left"), ("view", "left"),
        ("ms (median)", "right"), ("min-max", "right"), ("cores busy", "right"), ("M samples", "right"),
        ("M samples/s", "right"), ("cycles / sample", "right"), ("samples / oracle", "right"), ("vs naive", "right"), ("bytes", "right"), ("notes", "left"),
    ):
        table.add_column(col, justify=justify)  # type: ignore[arg-type]
    for r in records:
        if r["phase"] == "section_done":
            continue
        notes = []
        if r["phase"] == "skipped":
            notes.append(r.get("reason") or "")
        if r.get("psnr_vs_naive") is not None:
            notes.append(f"PSNR {r['psnr_vs_naive']:.1f} dB vs naive")
        if r.get("ratio_to_best") is not None:
            notes.append(f"{r['ratio_to_best']:.1f}x our best"
                         + (f" taking {r['samples_vs_naive']:.2f}x naive's samples"
                            if r.get("samples_vs_naive") is not None else ""))
        if r.get("occupancy") is not None:
            notes.append(f"occupancy {100 * r['occupancy']:.1f}% of {r['bricks']} bricks")
        if r.get("table_size") is not None:
            notes.append(f"{r['table_size']} entries" + (f", {r['queries']} ranges" if r.get("queries") else ""))
        if r["phase"] == "render" and r.get("width"):
            notes.append(f"{r['width']}x{r['height']}" + (f" dt={r['dt']:g}" if r.get("dt") else ""))
        spec = ".3f" if (r.get("ms") or 0) < 10 else ".1f"
        table.add_row(
            str(r.get("dataset") or ""), r.get("tf") or "", r.get("method") or "", r["phase"] or "",
            r.get("view") or "", _fmt(r.get("ms"), spec),
            f"{_fmt(r['ms_min'], spec)}-{_fmt(r['ms_max'], spec)}" if r.get("ms_min") is not None else "",
            _fmt(r.get("cores_busy"), ".2f"),
            _fmt(None if r.get("samples") is None else r["samples"] / 1e6, ".2f"),
            _fmt(r.get("msamples_per_s"), ".1f"), _fmt(r.get("cycles_per_sample"), ".0f"),
            _fmt(r.get("samples_vs_oracle"), ".1f"),
            _fmt(r.get("speedup_vs_naive"), ".2f"),
            _fmt(r.get("bytes"), ",d"),
            "; ".join(notes),
        )
    table.caption = _timing_caption(records)
    return table


def _timing_caption(records: list[dict[str, Any]]) -> str:
    """How the render figures were taken (rounds, spread, clock)."""
    renders = [r for r in records if r.get("phase") == "render" and r.get("ms_runs") and not r.get("section")]
    if not renders:
        return ""
    rounds = sorted({len(r["ms_runs"]) for r in renders})
    m = renders[0].get("machine") or {}
    clock = (f"{m['clock_ghz']:.2f} GHz nominal ({m.get('clock_source')})" if m.get("clock_ghz")
             else "unknown clock: no cycles")
    return (f"frame ms: median of {'/'.join(map(str, rounds))} interleaved rounds (methods and peers in turn, "
            f"after a warm-up round); min-max of those runs; cores busy = CPU / wall; "
            f"cycles / sample = CPU time x {clock} / samples")


def format_summary(records: list[dict[str, Any]]):
    """A :class:`rich.table.Table` with the headline per (dataset, TF, size): the best
    exact index, its speed-up over naive and each peer, work efficiency, rebuild ms."""
    from rich.table import Table

    from .summary import best_rows

    rows, peers = best_rows(records)
    table = Table(title="sparsecast bench: best index per dataset (details in the report / JSON)")
    for col in ["dataset", "tf", "size", "best", "frame ms", "spread %", "cores busy", "cycles / sample",
                "x naive", "samples / oracle", "cell bound", "rebuild ms", *[f"x {p}" for p in peers]]:
        table.add_column(col, justify="left" if col in ("dataset", "tf", "size", "best") else "right")
    for b in rows:
        vs = []
        for p in peers:
            cell = _fmt(b.vs_peers[p], ".1f")
            if b.peer_samples.get(p) is not None:  # a peer taking other samples than ours says so
                cell += f" ({b.peer_samples[p]:.2f}x samples)"
            vs.append(cell)
        table.add_row(b.dataset, b.tf, f"{b.width}x{b.height}", b.best.method, _fmt(b.best.ms, ".1f"),
                      _fmt(b.best.spread_pct, ".0f"), _fmt(b.best.cores_busy, ".2f"),
                      _fmt(b.best.cycles_per_sample, ".0f"),
                      _fmt(b.best.speedup_vs_naive, ".1f"), _fmt(b.best.work_efficiency, ".2f"),
                      _fmt(b.cell_bound, ".2f"), _fmt(b.rebuild_ms, ".2f"), *vs)
    table.caption = _timing_caption(records) + (
        "; spread % = (max - min) / median of the timed runs, median over views" if rows else "")
    return table


def format_features(records: list[dict[str, Any]]):
    """The ``features`` section (:mod:`.features`) as a table, or None when the run has none:
    per case and variant the median frame ms of the interleaved rounds, min-max, cores
    busy, samples, the speed-up within the case and the max abs diff against naive."""
    from rich.table import Table

    rows = [r for r in records if r.get("section") == "features" and r.get("phase") == "render"]
    if not rows:
        return None
    table = Table(title="sparsecast bench: labels, clipping, isosurfaces, shading (interleaved rounds per case)")
    for col in ("dataset", "case", "variant", "index", "size", "ms (median)", "min-max", "cores busy",
                "M samples", "speed-up", "samples ratio", "max |diff| vs naive"):
        table.add_column(col, justify="left" if col in ("dataset", "case", "variant", "index", "size") else "right")
    for r in rows:
        case = str(r.get("case")) + (f" ({r['tf']} TF)" if r.get("tf") else "")
        table.add_row(str(r.get("dataset")), case, str(r.get("variant")), str(r.get("method")),
                      f"{r.get('width')}x{r.get('height')}", _fmt(r.get("ms"), ".1f"),
                      f"{_fmt(r.get('ms_min'), '.1f')}-{_fmt(r.get('ms_max'), '.1f')}",
                      _fmt(r.get("cores_busy"), ".2f"), _fmt((r.get("samples") or 0) / 1e6, ".2f"),
                      _fmt(r.get("speedup"), ".2f"), _fmt(r.get("sample_ratio"), ".2f"),
                      _fmt(r.get("max_abs_diff"), ".1e"))
    table.caption = ("speed-up: labels all / half hidden, clip unclipped / half box (per index), iso naive / "
                     "index, shading shaded / unshaded (on the unshaded row: what shading costs); samples ratio: "
                     "the same of the samples taken; "
                     "ratios of medians within one interleaved run")
    return table


def format_surface(records: list[dict[str, Any]]):
    """The ``surface`` section (:mod:`.surface`) as a table, or None when the run has none:
    per mesh and method the build, the primary and diffuse rays per CPU-second (all
    threads: the fair figure beside a peer with its own thread count), their ratios to
    the exact BVH and to Embree in the same interleaved run, PSNR and memory."""
    from rich.table import Table

    sec = [r for r in records if r.get("section") == "surface"]
    prim = {(r["dataset"], r["method"]): r for r in sec if r.get("phase") == "render"}
    if not prim:
        return None
    diff = {(r["dataset"], r["method"]): r for r in sec if r.get("phase") == "render_diffuse"}
    build = {(r["dataset"], r["method"]): r for r in sec if r.get("phase") == "build"}
    mem = {(r["dataset"], r["method"]): r for r in sec if r.get("phase") == "memory"}
    tris = {r["dataset"]: r.get("triangles") for r in sec if r.get("phase") == "load"}

    def ratio(rows, key, ref_method):
        ref = rows.get((key[0], ref_method))
        a, b = (rows.get(key) or {}).get("mrays_cpu_s"), (ref or {}).get("mrays_cpu_s")
        return a / b if a and b else None

    table = Table(title="sparsecast bench: surfaces (interleaved rounds per mesh, per CPU-second)")
    for col in ("mesh", "triangles", "method", "build ms", "primary ms", "min-max", "cores busy",
                "M rays / CPU-s", "x bvh", "x embree", "diffuse M rays / CPU-s", "diffuse x embree",
                "PSNR dB", "memory / bvh"):
        table.add_column(col, justify="left" if col in ("mesh", "method") else "right")
    for key, r in prim.items():
        b = build.get(key) or {}
        d = diff.get(key) or {}
        table.add_row(str(key[0]), _fmt(tris.get(key[0]), "d"), str(key[1]), _fmt(b.get("ms"), ".0f"),
                      _fmt(r.get("ms"), ".1f"), f"{_fmt(r.get('ms_min'), '.1f')}-{_fmt(r.get('ms_max'), '.1f')}",
                      _fmt(r.get("cores_busy"), ".2f"), _fmt(r.get("mrays_cpu_s"), ".2f"),
                      _fmt(ratio(prim, key, "bvh"), ".2f"), _fmt(ratio(prim, key, "embree"), ".2f"),
                      _fmt(d.get("mrays_cpu_s"), ".2f"), _fmt(ratio(diff, key, "embree"), ".2f"),
                      _fmt(r.get("psnr"), ".1f"), _fmt((mem.get(key) or {}).get("mem_ratio"), ".3f"))
    table.caption = ("build: median after a warm-up (Embree's includes its first cast); ratios of rays per "
                     "CPU-second within one run; PSNR of the shaded image against the exact BVH's")
    return table


def format_scale(records: list[dict[str, Any]]):
    """The ``scale`` section (:mod:`.scale`) as a table, or None when the run has none: per
    size and source kind, opening, statistics, time to first image and peak RSS, then one
    row per index with its first build, rebuild and frame."""
    from rich.table import Table

    rows = [r for r in records if r.get("section") == "scale" and r.get("phase") in ("load", "render", "skipped")]
    if not rows:
        return None
    table = Table(title="sparsecast bench: volumes larger than memory (one process per size and kind)")
    for col in ("dataset", "kind", "storage", "index", "open ms", "stats G vox/s", "first image ms",
                "build ms", "rebuild ms", "frame ms", "peak RSS MiB", "RSS / dense", "resident bricks",
                "notes"):
        table.add_column(col, justify="left" if col in ("dataset", "kind", "storage", "index", "notes") else "right")
    for r in rows:
        if r["phase"] == "load":
            table.add_row(str(r.get("dataset")), str(r.get("kind")), str(r.get("storage")), "(open)",
                          _fmt(r.get("open_ms"), ".0f"), _fmt(r.get("stats_gvox_s"), ".2f"),
                          _fmt(r.get("first_image_ms"), ".0f"), "", "", "",
                          _fmt((r.get("peak_rss") or 0) / 2**20, ".0f"), _fmt(r.get("rss_over_dense"), ".3f"),
                          f"{r.get('resident_bricks')} / {r.get('bricks')}",
                          f"occupancy {100 * (r.get('occupancy') or 0):.1f} %; auto: {r.get('first_index')}")
        elif r["phase"] == "render":
            table.add_row(str(r.get("dataset")), str(r.get("kind")), "", str(r.get("method")), "", "", "",
                          _fmt(r.get("build_ms"), ".1f"), _fmt(r.get("rebuild_ms"), ".1f"),
                          _fmt(r.get("ms"), ".1f"), "", "", "", f"{r.get('width')}x{r.get('height')}")
        else:
            table.add_row(str(r.get("dataset")), str(r.get("kind")), "", str(r.get("method")),
                          *[""] * 9, str(r.get("reason") or "skipped"))
    table.caption = ("open: load_volume (a lazy volume's statistics pass included); first image: load_volume "
                     "to the first render(index='auto'); frame: median of the timed frames after a warm-up; "
                     "peak RSS: VmHWM of the case's own process")
    return table


def write_json(records: list[dict[str, Any]], path: str | os.PathLike) -> Path:
    """Write ``records`` as a JSON list (atomically)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(p) as tmp:
        tmp.write_text(json.dumps(records, indent=1, default=float))
    return p


def load_records(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Records from a JSON list (``--json`` output) or a JSONL journal."""
    p = Path(path)
    text = p.read_text()
    try:
        if p.suffix.lower() == ".jsonl":
            return [json.loads(line) for line in text.splitlines() if line.strip()]
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"records {str(p)!r}: not valid JSON ({exc}); expected `sparsecast bench` output") from None
    if not isinstance(data, list) or not all(isinstance(r, dict) and "phase" in r for r in data):
        raise FileFormatError(f"records {str(p)!r}: expected a JSON list of benchmark records with a 'phase' each")
    return data
