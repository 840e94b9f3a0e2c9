"""Ratios between the render records of one run: speed-up over naive, samples per second,
samples against the oracle, and each peer against our best exact index."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

__all__ = ["add_ratios"]

Record = dict[str, Any]


def add_ratios(records: Iterable[Record]) -> None:
    """Ratios between records of the same run, added in place to every render record
    outside the sections (which compute their own).

    ``speedup_vs_naive`` (naive ms / ms, same dataset, TF, size and view),
    ``msamples_per_s``, ``samples_vs_oracle`` (samples taken / samples in non-empty
    space: 1 is a perfect skipper), ``cycles_per_sample`` (median CPU ms of a frame,
    all threads, times the machine's nominal clock, over the samples: nominal, see
    :func:`~.machine.nominal_clock_ghz`) and, for peers, ``ratio_to_best`` (peer ms /
    ms of our fastest exact index on the same case, both medians of the same
    interleaved rounds: above 1 means we are faster) and, where the peer reports its
    samples, ``samples_vs_naive`` (its samples / our naive marcher's on that case).
    """
    recs = [r for r in records if r.get("phase") == "render" and not r.get("section")]

    def case(r: Record) -> tuple:
        return (r["dataset"], r["tf"], r["view"], r.get("width"), r.get("height"))

    naive = {case(r): r["ms"] for r in recs if r["method"] == "naive"}
    naive_samples = {case(r): r.get("samples") for r in recs if r["method"] == "naive"}
    best: dict[tuple, float] = {}
    for r in recs:
        if not r.get("peer") and r.get("exact", True) and r["ms"]:
            best[case(r)] = min(best.get(case(r), float("inf")), r["ms"])
    for r in recs:
        base = naive.get(case(r))
        r["speedup_vs_naive"] = base / r["ms"] if base and r["ms"] else None
        samples, ne = r.get("samples"), r.get("samples_nonempty")
        r["msamples_per_s"] = samples / r["ms"] / 1e3 if samples and r["ms"] else None
        r["samples_vs_oracle"] = samples / ne if samples and ne else None
        clock = (r.get("machine") or {}).get("clock_ghz")
        cpu = r.get("cpu_ms")
        r["cycles_per_sample"] = cpu * 1e-3 * clock * 1e9 / samples if samples and cpu and clock else None
        if r.get("peer"):
            b = best.get(case(r))
            r["ratio_to_best"] = r["ms"] / b if b else None
            ns = naive_samples.get(case(r))
            r["samples_vs_naive"] = samples / ns if samples and ns else None
