"""Benchmark records reduced to one row per case: the numbers reports and figures show.

A *case* is (dataset, tf, method, width, height); its frame time is the median over
views (the papers average over camera rotations), and every ratio is taken between
records of the same run.
"""

from __future__ import annotations

import re
import statistics
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

__all__ = ["SWEEP", "RenderRow", "BestRow", "render_rows", "best_exact", "best_rows", "build_ms", "peer_ratio"]

Record = dict[str, Any]

#: names of the synthetic sweep datasets (hybrid-grids paper, Fig. 5): family, parameter
SWEEP = re.compile(r"^(fig5[ab]-\d+)-[rk](\d+)$")


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
    samples, oracle : float or None
        Samples taken and oracle samples per frame (mean over views).
    psnr : float or None
        Median PSNR against our naive image (approximate indices, peers).
    spread_pct : float or None
        Median over views of (max - min) / median of the timed runs, in %.
    cores_busy, cycles_per_sample : float or None
        Medians over views (CPU / wall; CPU time at the nominal clock per sample).
    cell_bound : float or None
        Samples in occupied cells / oracle samples, summed over views: the least
        ``work_efficiency`` any index that skips by cells can reach
        (:mod:`.bounds`); recorded with the naive marcher's frames.
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
    samples: float | None
    oracle: float | None
    bytes: int | None
    psnr: float | None
    exact: bool
    peer: bool
    spread_pct: float | None = None
    cores_busy: float | None = None
    cycles_per_sample: float | None = None
    cell_bound: float | None = None

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
        bounded = [r for r in recs if r.get("samples_cell_bound") is not None]
        in_cells = sum(r["samples_cell_bound"] for r in bounded)
        bounded_oracle = sum(r.get("samples_nonempty") or 0 for r in bounded)
        rows.append(RenderRow(
            dataset=ds, tf=tf, method=method, width=w, height=h,
            ms=statistics.median(r["ms"] for r in recs), views=len(recs),
            speedup_vs_naive=_median([r.get("speedup_vs_naive") for r in recs]),
            work_efficiency=samples / oracle if samples and oracle else None,
            msamples_per_s=_median([r.get("msamples_per_s") for r in recs]),
            samples=samples / len(recs) if samples else None,
            oracle=oracle / len(recs) if oracle else None,
            bytes=recs[0].get("bytes"),
            psnr=_median([r.get("psnr_vs_naive") for r in recs]),
            exact=bool(recs[0].get("exact", True)),
            peer=bool(recs[0].get("peer", False)),
            spread_pct=_median([100.0 * (r["ms_max"] - r["ms_min"]) / r["ms"] for r in recs
                                if r.get("ms_max") is not None and r["ms"]]),
            cores_busy=_median([r.get("cores_busy") for r in recs]),
            cycles_per_sample=_median([r.get("cycles_per_sample") for r in recs]),
            cell_bound=in_cells / bounded_oracle if bounded and bounded_oracle else None,
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


@dataclass(frozen=True)
class BestRow:
    """The headline of one (dataset, tf, image size): our best exact index against
    naive and against each peer.

    Attributes
    ----------
    best : RenderRow
        Our fastest exact method (naive included).
    rebuild_ms : float or None
        What a TF edit costs that index (build with the volume's brick statistics cached).
    vs_peers : dict
        Peer name -> peer frame ms / our best frame ms on the peer's views (above 1:
        we are faster); None where the peer did not run.
    peer_samples : dict
        Peer name -> median over its views of its samples / our naive marcher's, for
        peers that report samples (yt steps per cell, not per unit length).
    cell_bound : float or None
        The naive row's :attr:`RenderRow.cell_bound`: the least samples / oracle of any
        cell-exact index on this case.
    """

    dataset: str
    tf: str
    width: int
    height: int
    dims: list[int] | None
    occupancy: float | None
    best: RenderRow
    naive_ms: float | None
    rebuild_ms: float | None
    vs_peers: dict[str, float | None]
    peer_samples: dict[str, float | None] = field(default_factory=dict)
    cell_bound: float | None = None


def peer_ratio(records: list[Record], dataset: str, tf: str, peer: str, width: int, height: int,
               ratio: str = "ratio_to_best") -> float | None:
    """Median over the peer's views of its ``ratio_to_best`` (peer ms / our best ms on
    that view), or of another of its ratios (``samples_vs_naive``)."""
    return _median([r.get(ratio) for r in records if r.get("phase") == "render"
                    and r.get("method") == peer and not r.get("section")
                    and (r["dataset"], r.get("tf"), r.get("width"), r.get("height")) == (dataset, tf, width, height)])


def best_rows(records: list[Record]) -> tuple[list[BestRow], list[str]]:
    """One :class:`BestRow` per (dataset, tf, size) with renders of ours, sparse TF
    first; and the names of the peers in the records."""
    rows = render_rows(records)
    builds = build_ms(records)
    peers = sorted({r.method for r in rows if r.peer})
    occupancy = {(r["dataset"], r.get("tf")): r.get("occupancy") for r in records
                 if r.get("phase") == "tf_classify" and not r.get("section")}
    dims = {r["dataset"]: r.get("dims") for r in records if r.get("phase") == "load" and not r.get("section")}
    naive = {(r.dataset, r.tf, r.width, r.height): r.ms for r in rows if r.method == "naive"}
    bound = {(r.dataset, r.tf, r.width, r.height): r.cell_bound for r in rows if r.method == "naive"}
    cases = sorted({(r.dataset, r.tf, r.width, r.height) for r in rows if not r.peer},
                   key=lambda c: (c[0], c[1] != "default", c[2] or 0))
    out = []
    for ds, tf, w, h in cases:
        best = best_exact(rows, ds, tf, w, h)
        if best is None:
            continue
        out.append(BestRow(
            dataset=ds, tf=tf, width=w, height=h, dims=dims.get(ds), occupancy=occupancy.get((ds, tf)),
            best=best, naive_ms=naive.get((ds, tf, w, h)),
            rebuild_ms=builds.get((ds, tf, best.method, "rebuild"), {}).get("ms"),
            vs_peers={p: peer_ratio(records, ds, tf, p, w, h) for p in peers},
            peer_samples={p: peer_ratio(records, ds, tf, p, w, h, "samples_vs_naive") for p in peers},
            cell_bound=bound.get((ds, tf, w, h)),
        ))
    return out, peers
