"""The Markdown report (``BENCHMARKS.md``): summary per dataset, per-method tables,
peers side by side, approximate methods, the other modules' sections and the figures.

Every number is a median from one run, and every ratio compares records of that
same run (timings on a shared machine vary by about +-20 % between runs).
"""

from __future__ import annotations

import os
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

from ..io.atomic import atomic_path
from .summary import RenderRow, best_exact, build_ms, render_rows

__all__ = ["markdown_report", "write_markdown"]

Record = dict[str, Any]
_NOT_EXTRA = {"machine", "ms_runs", "section", "index_stats"}


def _f(v: Any, spec: str = ".1f", suffix: str = "") -> str:
    if v is None:
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
        f"Written by `sparsecast bench{' --suite ' + suite if suite else ''}` on "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.",
        "",
        f"**Machine:** {m.get('cpu', '?')}, {m.get('cores', '?')} cores "
        f"({m.get('numba_threads', '?')} Numba threads), Python {m.get('python', '?')}, "
        f"NumPy {m.get('numpy', '?')}, Numba {m.get('numba', '?')}, {m.get('platform', '?')}.",
        "",
    ]
    if rows:
        out += [
            f"Image sizes {', '.join(sizes)}; frame time = median over up to {views} orbit views; "
            "every ratio compares two measurements of this same run (timings on a shared "
            "machine vary by about ±20 % between runs). *Work efficiency* = samples taken / "
            "samples in non-empty space (the oracle; 1.0 is a perfect skipper). "
            "*Rebuild* = building the index again after a TF change (per-volume brick "
            "statistics reused).",
            "",
        ]
    out += _summary(rows, builds, records)
    out += _per_dataset(rows, builds)
    out += _peers(rows, records, rel)
    out += _approximate(rows)
    out += _sections(records)
    out += _skipped(records)
    if figures:
        out += ["## Figures", ""] + [f"![{Path(f).stem}]({rel(f)})" for f in figures] + [""]
    return "\n".join(out).rstrip() + "\n"


def _summary(rows: list[RenderRow], builds: dict, records: list[Record]) -> list[str]:
    peers = sorted({r.method for r in rows if r.peer})
    occupancy = {(r["dataset"], r["tf"]): r.get("occupancy") for r in records if r.get("phase") == "tf_classify"}
    dims = {r["dataset"]: r.get("dims") for r in records if r.get("phase") == "load"}
    header = ["dataset", "TF", "size", "non-empty bricks", "best index", "frame ms", "naive ms",
              "× naive", "work eff.", "rebuild ms", "index bytes"] + [f"× {p}" for p in peers]
    table = []
    cases = sorted({(r.dataset, r.tf, r.width, r.height) for r in rows if not r.peer},
                   key=lambda c: (c[0], c[1] != "default", c[2]))
    for ds, tf, w, h in cases:
        best = best_exact(rows, ds, tf, w, h)
        if best is None:
            continue
        naive = next((r for r in rows if (r.dataset, r.tf, r.method, r.width, r.height) == (ds, tf, "naive", w, h)), None)
        rebuild = builds.get((ds, tf, best.method, "rebuild"), {}).get("ms")
        vs_peers = []
        for p in peers:
            peer = next((r for r in rows if (r.dataset, r.tf, r.method, r.width, r.height) == (ds, tf, p, w, h)), None)
            # Same views only: peers render the first views of the suite.
            vs_peers.append(_f(_peer_ratio(records, ds, tf, p, w, h), ".1f", "×") if peer else "–")
        label = ds + (f" ({'×'.join(map(str, dims[ds]))})" if dims.get(ds) else "")
        table.append([label, tf, f"{w}x{h}", _f(100 * occupancy[(ds, tf)] if occupancy.get((ds, tf)) is not None else None, ".1f", " %"),
                      f"`{best.method}`", _ms(best.ms), _ms(naive.ms if naive else None),
                      _f(best.speedup_vs_naive, ".1f", "×"), _f(best.work_efficiency, ".2f"), _ms(rebuild),
                      _bytes(best.bytes)] + vs_peers)
    if not table:
        return []
    return ["## Summary: best index per dataset", "",
            "Best = our fastest exact index; `× naive` = its speed-up over the naive marcher; "
            "`× vtk` / `× yt` = peer frame ms / our best frame ms on the same views (above 1: we are faster).",
            ""] + _table(header, table, "lllrlrrrrrr" + "r" * len(peers)) + [""]


def _peer_ratio(records: list[Record], ds: str, tf: str, peer: str, w: int, h: int) -> float | None:
    """Median over the peer's views of peer ms / our best ms on that view."""
    vals = [r["ratio_to_best"] for r in records if r.get("phase") == "render" and r.get("method") == peer
            and (r["dataset"], r.get("tf"), r.get("width"), r.get("height")) == (ds, tf, w, h)
            and r.get("ratio_to_best")]
    vals.sort()
    return vals[len(vals) // 2] if vals else None


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
        header = ["method", "first build ms", "rebuild ms", "bytes"]
        for w, h in sizes:
            header += [f"{w}² frame ms", f"{w}² × naive", f"{w}² work eff.", f"{w}² Msamples/s"]
        table = []
        for m in methods:
            b = builds.get((ds, tf, m, "build_cold"), {})
            rb = builds.get((ds, tf, m, "rebuild"), {})
            row = [f"`{m}`", _ms(b.get("ms")), _ms(rb.get("ms")), _bytes(rb.get("bytes"))]
            for w, h in sizes:
                r = next((x for x in rs if x.method == m and (x.width, x.height) == (w, h)), None)
                row += ([_ms(r.ms), _f(r.speedup_vs_naive, ".2f", "×"), _f(r.work_efficiency, ".2f"),
                         _f(r.msamples_per_s, ".0f")] if r else ["–"] * 4)
            table.append(row)
        out += [f"### {ds}, TF `{tf}`", ""] + _table(header, table) + [""]
    return out


def _peers(rows: list[RenderRow], records: list[Record], rel) -> list[str]:
    peer_recs = [r for r in records if r.get("phase") == "render" and r.get("peer")]
    if not peer_recs:
        return []
    ours_img = {(r["dataset"], r["tf"], r.get("width"), r.get("view")): r["image"] for r in records
                if r.get("phase") == "render" and r.get("image") and not r.get("peer")}
    table = []
    for p in [r for r in rows if r.peer]:
        best = best_exact(rows, p.dataset, p.tf, p.width, p.height)
        images = [r for r in peer_recs if (r["dataset"], r["tf"], r["method"], r["width"]) ==
                  (p.dataset, p.tf, p.method, p.width) and r.get("image")]
        pics = "–"
        if images:
            mine = ours_img.get((p.dataset, p.tf, p.width, images[0]["view"]))
            pics = f"[{p.method}]({rel(images[0]['image'])})" + (f" / [ours]({rel(mine)})" if mine else "")
        table.append([p.dataset, p.tf, p.size, p.method, str(p.views), _ms(p.ms),
                      f"`{best.method}` {_ms(best.ms)}" if best else "–",
                      _f(_peer_ratio(records, p.dataset, p.tf, p.method, p.width, p.height), ".1f", "×"),
                      _f(p.psnr, ".1f", " dB"), pics])
    return ["## Peers on the same cases", "",
            "Same volume, image size, step, camera and TF table (opacity corrected to the step "
            "with the same unit distance). PSNR: the peer's image against our naive image — an "
            "honesty check that the cases match, not a claim of equality (VTK quantises "
            "scalars to 15 bits; yt samples cell-centred data).", ""] + _table(
        ["dataset", "TF", "size", "peer", "views", "peer frame ms", "our best (ms)", "peer / our best",
         "PSNR vs naive", "images"], table, "lllllrrrrl") + [""]


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
              "bih": "Bounding interval hierarchy", "surface": "Surfaces: rasterized BVH"}
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
    return ["## Skipped", ""] + [f"- {r.get('kind', '')} `{r['method']}`: {r.get('reason', '')}" for r in notes] + [""]


def write_markdown(text: str, path: str | os.PathLike) -> Path:
    """Write the report atomically."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(p) as tmp:
        tmp.write_text(text)
    return p
