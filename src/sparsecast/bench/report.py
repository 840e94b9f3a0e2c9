"""Benchmark output: a console table and a JSON file of records."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..io.atomic import atomic_path

__all__ = ["format_table", "write_json"]


def _fmt(v: Any, spec: str) -> str:
    return "" if v is None else format(v, spec)


def format_table(records: list[dict[str, Any]]):
    """A :class:`rich.table.Table` with one row per record."""
    from rich.table import Table

    table = Table(title="sparsecast bench", show_lines=False)
    for col, justify in (
        ("dataset", "left"), ("tf", "left"), ("method", "left"), ("phase", "left"), ("view", "left"),
        ("ms (median)", "right"), ("M samples", "right"), ("M samples/s", "right"),
        ("samples / oracle", "right"), ("vs naive", "right"), ("bytes", "right"), ("notes", "left"),
    ):
        table.add_column(col, justify=justify)  # type: ignore[arg-type]
    for r in records:
        notes = []
        if r.get("occupancy") is not None:
            notes.append(f"occupancy {100 * r['occupancy']:.1f}% of {r['bricks']} bricks")
        if r.get("table_size") is not None:
            notes.append(f"{r['table_size']} entries" + (f", {r['queries']} ranges" if r.get("queries") else ""))
        if r["phase"] == "render":
            notes.append(f"{r['width']}x{r['height']} dt={r['dt']:g}")
        table.add_row(
            r["dataset"] or "", r.get("tf") or "", r["method"] or "", r["phase"] or "", r["view"] or "",
            _fmt(r["ms"], ".3f" if (r["ms"] or 0) < 10 else ".1f"),
            _fmt(None if r["samples"] is None else r["samples"] / 1e6, ".2f"),
            _fmt(r.get("msamples_per_s"), ".1f"),
            _fmt(r.get("samples_vs_oracle"), ".1f"),
            _fmt(r.get("speedup_vs_naive"), ".2f"),
            _fmt(r["bytes"], ",d"),
            "; ".join(notes),
        )
    return table


def write_json(records: list[dict[str, Any]], path: str | os.PathLike) -> Path:
    """Write ``records`` as a JSON list (atomically)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(p) as tmp:
        tmp.write_text(json.dumps(records, indent=1, default=float))
    return p
