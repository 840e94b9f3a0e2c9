"""The Markdown report (``BENCHMARKS.md``): summary per dataset, per-method tables,
peers side by side, approximate methods, the other modules' sections and the figures.

Every number is a median from one run, and every ratio compares records of that
same run (timings on a shared machine vary by about +-20 % between runs).
"""

from __future__ import annotations

import os
import statistics
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

from .._util.atomic import atomic_path
from .summary import SWEEP, RenderRow, best_exact, best_rows, build_ms, peer_ratio, render_rows

__all__ = ["markdown_report", "write_markdown"]

Record = dict[str, Any]
_NOT_EXTRA = {"machine", "ms_runs", "section", "index_stats"}


def _f(v: Any, spec: str = ".1f", suffix: str = "") -> str:
    if v is None or (isinstance(v, float) and v != v):  # None or NaN
        return "–"
    try:
        return format(v, spec) + suffix
    except (TypeError, ValueError):
        return str(v)


def _ms(v: float | None) -> str:
    if v is None:
        return "–"
    return f"{v:.3f}" if v < 1 else f"{v:.2f}" if v < 10 else f"{v:.1f}" if v < 1000 else f"{v:,.0f}"


def _bytes(v: int | None) -> str:
    if v is None:
        return "–"
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if v >= scale:
            return f"{v / scale:.1f} {unit}"
    return f"{v} B"


def _table(header: list[str], rows: list[list[str]], align: str | None = None) -> list[str]:
    align = align or "l" + "r" * (len(header) - 1)
    sep = ["---:" if a == "r" else "---" for a in align]
    return ["| " + " | ".join(header) + " |", "| " + " | ".join(sep) + " |"] + [
        "| " + " | ".join(r) + " |" for r in rows
    ]


def _machine(records: list[Record]) -> dict[str, Any]:
    for r in records:
        if r.get("machine"):
            return r["machine"]
    return {}


def markdown_report(
    records: list[Record],
    *,
    title: str = "sparsecast benchmarks",
    suite: str | None = None,
    command: str | None = None,
    figures: list[Path] | None = None,
    relative_to: Path | None = None,
) -> str:
    """The report as Markdown text (see the module docstring for its sections)."""
    rows = render_rows(records)
    builds = build_ms(records)
    m = _machine(records)
    base = relative_to or Path.cwd()

    def rel(p: str | Path) -> str:
        return Path(os.path.relpath(Path(p).resolve(), base.resolve())).as_posix()

    out = [f"# {title}", ""]
    sizes = sorted({r.size for r in rows}, key=lambda s: int(s.split("x")[0]))
    views = max((r.views for r in rows if not r.peer), default=0)
    out += [
        f"Written by `{command or 'sparsecast bench' + (' --suite ' + suite if suite else '')}` on "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.",
        "",
        f"**Machine:** {m.get('cpu', '?')}, {m.get('cores', '?')} cores "
        f"({m.get('numba_threads', '?')} Numba threads), Python {m.get('python', '?')}, "
        f"NumPy {m.get('numpy', '?')}, Numba {m.get('numba', '?')}, {m.get('platform', '?')}.",
        "",
    ]
    if rows:
        out += [
            f"Image sizes {', '.join(sizes)}; per view, every method and peer renders in turn "
            f"(A B C A B C ...): a warm-up round, then {_rounds(records)} timed rounds, whose median "
            f"is the view's frame time; frame time = median over up to {views} orbit views; "
            f"cycles / sample = CPU time (all threads) x the nominal clock ({_clock(m)}) / samples; "
            "every ratio compares two medians of the same interleaved rounds (timings on a shared "
            "machine vary by about ±20 % between runs). *Work efficiency* = samples taken / "
            "samples in non-empty space (the oracle; 1.0 is a perfect skipper); *cell bound* = the "
            "same ratio for a perfect skipper at cell granularity (the naive marcher's samples in cells "
            "whose corner range the TF makes visible: no index that decides by cells takes fewer). "
            "*Rebuild* = building the index again after a TF change (per-volume brick "
            "statistics reused).",
            "",
        ]
    out += _summary(records)
    out += _per_dataset([r for r in rows if not SWEEP.match(r.dataset)], builds)
    out += _sweeps(rows, records)
    out += _peers(rows, records, rel)
    out += _approximate(rows)
    out += _sections(records)
    out += _skipped(records)
    if figures:
        out += ["## Figures", ""] + [f"![{Path(f).stem}]({rel(f)})" for f in figures] + [""]
    return "\n".join(out).rstrip() + "\n"


def _summary(records: list[Record]) -> list[str]:
    best, peers = best_rows(records)
    best = [b for b in best if not SWEEP.match(b.dataset)]  # the sweeps have their own table
    if not best:
        return []
    header = ["dataset", "TF", "size", "non-empty bricks", "best index", "frame ms", "naive ms",
              "× naive", "work eff.", "cell bound", "rebuild ms", "index bytes"] + [f"× {p}" for p in peers]
    table = []
    for b in best:
        label = b.dataset + (f" ({'×'.join(map(str, b.dims))})" if b.dims else "")
        occupancy = None if b.occupancy is None else 100 * b.occupancy
        table.append([label, b.tf, f"{b.width}x{b.height}", _f(occupancy, ".1f", " %"), f"`{b.best.method}`",
                      _ms(b.best.ms), _ms(b.naive_ms), _f(b.best.speedup_vs_naive, ".1f", "×"),
                      _f(b.best.work_efficiency, ".2f"), _f(b.cell_bound, ".2f"), _ms(b.rebuild_ms),
                      _bytes(b.best.bytes)]
                     + [_f(b.vs_peers[p], ".1f", "×") for p in peers])
    return ["## Summary: best index per dataset", "",
            "Best = our fastest exact index; `× naive` = its speed-up over the naive marcher; "
            "`× vtk` / `× yt` = peer frame ms / our best frame ms on the same views (above 1: we are faster).",
            ""] + _table(header, table, "lllrlrrrrrrr" + "r" * len(peers)) + [""]


def _per_dataset(rows: list[RenderRow], builds: dict) -> list[str]:
    out = ["## Per dataset and transfer function", ""]
    groups: dict[tuple[str, str], list[RenderRow]] = defaultdict(list)
    for r in rows:
        if not r.peer:
            groups[(r.dataset, r.tf)].append(r)
    if not groups:
        return []
    for (ds, tf), rs in groups.items():
        sizes = sorted({(r.width, r.height) for r in rs})
        methods = list(dict.fromkeys(r.method for r in rs))
        header = ["method", "first build ms", "rebuild ms", "rebuild phases (ms)", "bytes"]
        for w, h in sizes:
            header += [f"{w}² frame ms", f"{w}² × naive", f"{w}² M samples (oracle)", f"{w}² work eff."]
        table = []
        for m in methods:
            b = builds.get((ds, tf, m, "build_cold"), {})
            rb = builds.get((ds, tf, m, "rebuild"), {})
            phases = (rb.get("index_stats") or {}).get("phases") or {}
            steps = " · ".join(f"{k} {_ms(v)}" for k, v in phases.items() if v is not None) or "–"
            row = [f"`{m}`", _ms(b.get("ms")), _ms(rb.get("ms")), steps, _bytes(rb.get("bytes"))]
            for w, h in sizes:
                r = next((x for x in rs if x.method == m and (x.width, x.height) == (w, h)), None)
                taken = f"{_f(r.samples and r.samples / 1e6, '.2f')} ({_f(r.oracle and r.oracle / 1e6, '.2f')})" if r else ""
                row += ([_ms(r.ms), _f(r.speedup_vs_naive, ".2f", "×"), taken, _f(r.work_efficiency, ".2f")]
                        if r else ["–"] * 4)
            table.append(row)
        out += [f"### {ds}, TF `{tf}`", ""] + _table(header, table, "lrrl" + "r" * (len(header) - 4)) + [""]
    return out


def _sweeps(rows: list[RenderRow], records: list[Record]) -> list[str]:
    """Speed-up over naive along each synthetic sweep (the table behind Fig. 5)."""
    sweep = [r for r in rows if SWEEP.match(r.dataset) and r.tf == "default" and not r.peer]
    if not sweep:
        return []
    occupancy = {r["dataset"]: r.get("occupancy") for r in records
                 if r.get("phase") == "tf_classify" and r.get("tf") == "default"}
    methods = [m for m in dict.fromkeys(r.method for r in sweep) if m != "naive"]
    table = []
    for ds in dict.fromkeys(r.dataset for r in sweep):
        mine = {r.method: r for r in sweep if r.dataset == ds}
        naive = mine.get("naive")
        occ = occupancy.get(ds)
        table.append([ds, _f(None if occ is None else 100 * occ, ".1f", " %"), _ms(naive.ms if naive else None)]
                     + [_f(mine[m].speedup_vs_naive, ".1f", "×") if m in mine else "–" for m in methods])
    return ["## Cluster sweeps (Fig. 5)", "",
            "Speed-up over naive (median over views) as clusters grow (`fig5a`, radius in % of the edge) "
            "and multiply (`fig5b`, number of clusters).", ""] + _table(
        ["dataset", "non-empty bricks", "naive ms"] + [f"`{m}`" for m in methods], table) + [""]


def _rounds(records: list[Record]) -> str:
    """The timed rounds per view in these records (e.g. ``3``, or ``1/3`` for a mixed journal)."""
    counts = sorted({len(r["ms_runs"]) for r in records if r.get("phase") == "render" and r.get("ms_runs")
                     and not r.get("section")})
    return "/".join(map(str, counts)) or "?"


def _clock(m: dict[str, Any]) -> str:
    return f"{m['clock_ghz']:.2f} GHz from {m.get('clock_source')}" if m.get("clock_ghz") else "unknown"


def _peers(rows: list[RenderRow], records: list[Record], rel) -> list[str]:
    peer_recs = [r for r in records if r.get("phase") == "render" and r.get("peer")]
    if not peer_recs:
        return []
    table = []
    for p in [r for r in rows if r.peer]:
        best = best_exact(rows, p.dataset, p.tf, p.width, p.height)
        image = next((r["image"] for r in peer_recs if (r["dataset"], r["tf"], r["method"], r["width"]) ==
                      (p.dataset, p.tf, p.method, p.width) and r.get("image")), None)
        cores = statistics.median([r["cores_busy"] for r in peer_recs if r.get("cores_busy") is not None and
                                   (r["dataset"], r["tf"], r["method"], r["width"]) == (p.dataset, p.tf, p.method, p.width)]
                                  or [float("nan")])
        table.append([p.dataset, p.tf, p.size, p.method, str(p.views), _ms(p.ms), _f(cores, ".1f"),
                      f"`{best.method}` {_ms(best.ms)}" if best else "–",
                      _f(peer_ratio(records, p.dataset, p.tf, p.method, p.width, p.height), ".1f", "×"),
                      _f(peer_ratio(records, p.dataset, p.tf, p.method, p.width, p.height, "samples_vs_naive"),
                         ".2f", "×"),
                      _f(p.psnr, ".1f", " dB"), f"`{Path(image).name}`" if image else "–"])
    folders = sorted({rel(Path(r["image"]).parent) for r in records if r.get("image") and r.get("peer")})
    where = (" The images (ours as `*_sparsecast.png`, rendered by the naive marcher) are in "
             + ", ".join(f"`{f}/`" for f in folders) + ".") if folders else ""
    return ["## Peers on the same cases", "",
            "Same volume, image size, step, camera and TF table (opacity corrected to the step "
            "with the same unit distance). PSNR: the peer's image against our naive image — an "
            "honesty check that the cases match, not a claim of equality (VTK quantises "
            "scalars to 15 bits; yt samples cell-centred data per cell crossing). *Cores busy*: the "
            "peer's CPU time / wall time while timed, measured for ours the same way. *Samples / "
            "naive*: for a peer that reports them (yt: `num_samples` per cell crossing, estimated "
            "from the rays' cell crossings), its samples over our naive marcher's on the same "
            "view." + where, ""] + _table(
        ["dataset", "TF", "size", "peer", "views", "peer frame ms", "cores busy", "our best (ms)",
         "peer / our best", "samples / naive", "PSNR vs naive", "image"], table, "lllllrrrrrrl") + [""]


def _approximate(rows: list[RenderRow]) -> list[str]:
    approx = [r for r in rows if not r.exact and not r.peer]
    if not approx:
        return []
    table = [[r.dataset, r.tf, r.size, f"`{r.method}`", _ms(r.ms), _f(r.speedup_vs_naive, ".2f", "×"),
              _f(r.psnr, ".1f", " dB")] for r in approx]
    return ["## Approximate indices", "", "Image quality against the naive marcher on the same views.", ""] + _table(
        ["dataset", "TF", "size", "method", "frame ms", "× naive", "PSNR"], table) + [""]


def _sections(records: list[Record]) -> list[str]:
    """One table per section and phase, with the columns those records fill."""
    by_section: dict[str, list[Record]] = defaultdict(list)
    for r in records:
        if r.get("section") and r.get("phase") not in ("section_done", "skipped"):
            by_section[r["section"]].append(r)
    out = []
    titles = {"irt": "Transfer-function range queries (iterative range tree vs prefix count)",
              "bih": "Bounding interval hierarchy", "surface": "Surfaces: rasterized BVH",
              "scale": "Volumes larger than memory", "distributed": "Rendering on a Dask cluster"}
    for name, recs in by_section.items():
        out += [f"## {titles.get(name, name)}", ""]
        by_phase: dict[str, list[Record]] = defaultdict(list)
        for r in recs:
            by_phase[str(r.get("phase"))].append(r)
        for phase, rows in by_phase.items():
            extra = list(dict.fromkeys(k for r in rows for k, v in r.items()
                                       if v is not None and k not in _NOT_EXTRA
                                       and k not in ("dataset", "method", "phase", "ms")))
            header = ["dataset", "method", "ms"] + extra
            table = [[str(r.get("dataset") or ""), f"`{r.get('method') or ''}`", _ms(r.get("ms"))]
                     + [_cell(r.get(k)) for k in extra] for r in rows]
            out += [f"*{phase}*", ""] + _table(header, table, "ll" + "r" * (len(header) - 2)) + [""]
    return out


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, dict)):
        return "`" + str(v)[:40] + "`"
    return str(v)


def _skipped(records: list[Record]) -> list[str]:
    notes = [r for r in records if r.get("phase") == "skipped"]
    if not notes:
        return []
    lines = []
    for r in notes:
        kind = f"{r['kind']} " if r.get("kind") else ""
        lines.append(f"- {kind}`{r['method']}`: {r.get('reason', '')}")
    return ["## Skipped", ""] + lines + [""]


def write_markdown(text: str, path: str | os.PathLike) -> Path:
    """Write the report atomically."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(p) as tmp:
        tmp.write_text(text)
    return p
