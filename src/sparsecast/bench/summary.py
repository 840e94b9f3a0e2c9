"""Benchmark records reduced to one row per case: the numbers reports and figures show.

A *case* is (dataset, tf, method, width, height); its frame time is the median over
views (the papers average over camera rotations), and every ratio is taken between
records of the same run.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

__all__ = ["RenderRow", "render_rows", "best_exact", "build_ms"]

Record = dict[str, Any]


@dataclass(frozen=True)
class RenderRow:
    """One method on one (dataset, tf, image size), over all its views.

    Attributes
    ----------
    ms : float
        Median frame time over views.
    speedup_vs_naive : float or None
        Median over views of naive ms / ms (same run).
    work_efficiency : float or None
        Samples taken / oracle samples (in non-empty space), summed over views:
        1.0 is a perfect empty-space skipper; peers have none.
    psnr : float or None
        Median PSNR against our naive image (approximate indices, peers).
    """

    dataset: str
    tf: str
    method: str
    width: int
    height: int
    ms: float
    views: int
    speedup_vs_naive: float | None
    work_efficiency: float | None
    msamples_per_s: float | None
    bytes: int | None
    psnr: float | None
    exact: bool
    peer: bool

    @property
    def size(self) -> str:
        return f"{self.width}x{self.height}"


def _median(values: list[float]) -> float | None:
    vals = [v for v in values if v is not None]
    return statistics.median(vals) if vals else None


def render_rows(records: list[Record]) -> list[RenderRow]:
    """One :class:`RenderRow` per (dataset, tf, method, size), in record order."""
    groups: dict[tuple, list[Record]] = defaultdict(list)
    for r in records:
        # Sections (bih, surface, ...) have tables of their own in the report.
        if r.get("phase") == "render" and r.get("ms") is not None and not r.get("section"):
            groups[(r["dataset"], r.get("tf"), r["method"], r.get("width"), r.get("height"))].append(r)
    rows = []
    for (ds, tf, method, w, h), recs in groups.items():
        samples = sum(r.get("samples") or 0 for r in recs)
        oracle = sum(r.get("samples_nonempty") or 0 for r in recs)
        rows.append(RenderRow(
            dataset=ds, tf=tf, method=method, width=w, height=h,
            ms=statistics.median(r["ms"] for r in recs), views=len(recs),
            speedup_vs_naive=_median([r.get("speedup_vs_naive") for r in recs]),
            work_efficiency=samples / oracle if samples and oracle else None,
            msamples_per_s=_median([r.get("msamples_per_s") for r in recs]),
            bytes=recs[0].get("bytes"),
            psnr=_median([r.get("psnr_vs_naive") for r in recs]),
            exact=bool(recs[0].get("exact", True)),
            peer=bool(recs[0].get("peer", False)),
        ))
    return rows


def best_exact(rows: list[RenderRow], dataset: str, tf: str, width: int, height: int) -> RenderRow | None:
    """Our fastest exact method (naive included) on one (dataset, tf, size)."""
    mine = [r for r in rows if (r.dataset, r.tf, r.width, r.height) == (dataset, tf, width, height)
            and r.exact and not r.peer]
    return min(mine, key=lambda r: r.ms) if mine else None


def build_ms(records: list[Record]) -> dict[tuple[str, str, str, str], Record]:
    """(dataset, tf, method, phase) -> the ``build_cold`` / ``rebuild`` record."""
    return {(r["dataset"], r.get("tf"), r["method"], r["phase"]): r for r in records
            if r.get("phase") in ("build_cold", "rebuild") and not r.get("section")}
