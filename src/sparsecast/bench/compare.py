"""``sparsecast bench --compare old.json new.json``: per-case time ratios between two runs.

Cases are matched on their key (dataset, tf, method, size, view, phase, plus the
table size of TF-table records and the section a record comes from). The ratio is new ms / old ms: above 1 is slower.
Timings on a shared machine are noisy (about +-20 %), so only ratios beyond a
threshold are flagged.
"""

from __future__ import annotations

import json
import math
import statistics
from dataclasses import dataclass
from typing import Any

from .progress import case_key

__all__ = ["CaseRatio", "compare_records", "format_comparison"]


@dataclass(frozen=True)
class CaseRatio:
    """One case present in both runs."""

    key: tuple[Any, ...]
    old_ms: float
    new_ms: float

    @property
    def ratio(self) -> float:
        return self.new_ms / self.old_ms if self.old_ms > 0 else math.inf

    def label(self) -> str:
        dataset, tf, method, width, height, view, phase, table, section = self.key
        parts = [f"[{section}]" if section and section != "irt" else None, dataset, tf, method, phase,
                 f"{width}x{height}" if width else None, view, f"{table} entries" if table else None]
        return " ".join(str(p) for p in parts if p)


def _key(r: dict[str, Any]) -> tuple[Any, ...]:
    key = case_key(r) + (r.get("table_size"), r.get("section"))
    # Sections may put lists in these fields (a view as angles, a size as a pair).
    return tuple(json.dumps(v) if isinstance(v, (list, dict)) else v for v in key)


def compare_records(old: list[dict[str, Any]], new: list[dict[str, Any]]) -> tuple[list[CaseRatio], int, int]:
    """Timed cases of ``new`` matched to ``old``.

    Returns the matched cases (in ``new``'s order) and the number of timed cases
    found only in the old and only in the new run.
    """
    def timed(recs: list[dict[str, Any]]) -> dict[tuple[Any, ...], float]:
        return {_key(r): float(r["ms"]) for r in recs if r.get("ms") is not None}

    before, after = timed(old), timed(new)
    matched = [CaseRatio(k, before[k], ms) for k, ms in after.items() if k in before]
    return matched, len(before.keys() - after.keys()), len(after.keys() - before.keys())


def format_comparison(cases: list[CaseRatio], only_old: int, only_new: int, threshold: float = 1.25):
    """A :class:`rich.table.Table` of every matched case, ratios beyond ``threshold``
    (or below its inverse) highlighted, and a summary caption with the geometric mean."""
    from rich.table import Table

    table = Table(title="sparsecast bench --compare (new / old)")
    for col, justify in (("case", "left"), ("old ms", "right"), ("new ms", "right"), ("new / old", "right")):
        table.add_column(col, justify=justify)  # type: ignore[arg-type]
    slower = faster = 0
    for c in cases:
        style = ""
        if c.ratio > threshold:
            style, slower = "red", slower + 1
        elif c.ratio < 1.0 / threshold:
            style, faster = "green", faster + 1
        table.add_row(c.label(), f"{c.old_ms:.3f}", f"{c.new_ms:.3f}", f"{c.ratio:.2f}", style=style)
    finite = [c.ratio for c in cases if 0 < c.ratio < math.inf]
    geo = math.exp(statistics.fmean(math.log(r) for r in finite)) if finite else float("nan")
    table.caption = (
        f"{len(cases)} cases in both runs; geometric mean new/old {geo:.2f}; "
        f"{slower} slower and {faster} faster than x{threshold:g}; "
        f"{only_old} only in old, {only_new} only in new"
    )
    return table
