"""Figures in the style of the papers, drawn from benchmark records (matplotlib, PNG).

- ``frame_times.png``: frame ms per structure and dataset (median over views),
  log scale, with the naive marcher as a line (hybrid-grids paper, Fig. 3).
- ``build_times.png``: cold build and TF rebuild ms per structure and dataset
  (construction next to rendering, LBVH paper Fig. 4 / k-d tree paper Table 1).
- ``sweep_<family>.png``: speed-up over naive along a synthetic sweep
  (``fig5a-*``, ``fig5b-*`` datasets; hybrid-grids paper, Fig. 5), when present.
"""

from __future__ import annotations

import re
import statistics
from collections import defaultdict
from pathlib import Path
from typing import Any

from ..io.atomic import atomic_path

__all__ = ["write_plots"]


def _frame_ms(records, tf="default") -> dict[tuple[str, str], float]:
    """(dataset, method) -> median frame ms over views."""
    acc: dict[tuple[str, str], list[float]] = defaultdict(list)
    for r in records:
        if r["phase"] == "render" and r.get("tf") == tf:
            acc[(r["dataset"], r["method"])].append(r["ms"])
    return {k: statistics.median(v) for k, v in acc.items()}


def _save(fig, path: Path) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight")
    return path


def write_plots(records: list[dict[str, Any]], out_dir: str | Path) -> list[Path]:
    """Write the figures for ``records`` into ``out_dir``; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    sweep = re.compile(r"^(fig5[ab]-\d+)-[rk](\d+)$")
    frame = _frame_ms(records)
    datasets = sorted({d for d, _ in frame if not sweep.match(d)})
    methods = sorted({m for _, m in frame if m != "naive"})

    if datasets and methods:
        fig, axes = plt.subplots(1, len(datasets), figsize=(4.2 * len(datasets), 3.6), squeeze=False)
        for ax, ds in zip(axes[0], datasets):
            ms = [frame.get((ds, m), float("nan")) for m in methods]
            ax.bar(range(len(methods)), ms, color="tab:blue")
            if (ds, "naive") in frame:
                ax.axhline(frame[(ds, "naive")], color="tab:red", lw=1.5, label="naive")
                ax.legend(loc="upper right", fontsize=8)
            ax.set_yscale("log")
            ax.set_xticks(range(len(methods)), methods, rotation=45, ha="right", fontsize=8)
            ax.set_title(ds, fontsize=10)
        axes[0][0].set_ylabel("frame ms (median over views)")
        fig.suptitle("Frame time per structure (sparse TF)")
        fig.tight_layout()
        written.append(_save(fig, out / "frame_times.png"))
        plt.close(fig)

        build: dict[tuple[str, str, str], float] = {}
        for r in records:
            if r["phase"] in ("build_cold", "rebuild") and r.get("tf") == "default":
                build[(r["dataset"], r["method"], r["phase"])] = r["ms"]
        fig, axes = plt.subplots(1, len(datasets), figsize=(4.2 * len(datasets), 3.6), squeeze=False)
        for ax, ds in zip(axes[0], datasets):
            x = range(len(methods))
            cold = [build.get((ds, m, "build_cold"), 0.0) for m in methods]
            rebuild = [build.get((ds, m, "rebuild"), 0.0) for m in methods]
            render_ms = [frame.get((ds, m), 0.0) for m in methods]
            ax.bar([i - 0.27 for i in x], cold, width=0.27, label="first build")
            ax.bar(x, rebuild, width=0.27, label="rebuild (TF change)")
            ax.bar([i + 0.27 for i in x], render_ms, width=0.27, label="frame")
            ax.set_yscale("log")
            ax.set_xticks(list(x), methods, rotation=45, ha="right", fontsize=8)
            ax.set_title(ds, fontsize=10)
        axes[0][0].set_ylabel("ms")
        handles, labels = axes[0][0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=8)
        fig.suptitle("Construction vs rendering")
        fig.tight_layout(rect=(0, 0.07, 1, 1))
        written.append(_save(fig, out / "build_times.png"))
        plt.close(fig)

    families: dict[str, dict[str, list[tuple[int, float]]]] = defaultdict(lambda: defaultdict(list))
    for (ds, m), ms in frame.items():
        match = sweep.match(ds)
        if match and m != "naive" and (ds, "naive") in frame:
            families[match.group(1)][m].append((int(match.group(2)), frame[(ds, "naive")] / ms))
    for family, per_method in sorted(families.items()):
        fig, ax = plt.subplots(figsize=(5.5, 3.6))
        for m, pts in sorted(per_method.items()):
            pts.sort()
            ax.plot([p for p, _ in pts], [s for _, s in pts], marker="o", label=m)
        ax.axhline(1.0, color="tab:red", lw=1, label="naive")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("cluster radius (% of edge)" if family.startswith("fig5a") else "number of clusters")
        ax.set_ylabel("speed-up over naive")
        ax.set_title(family)
        ax.legend(fontsize=8)
        written.append(_save(fig, out / f"sweep_{family}.png"))
        plt.close(fig)
    return written
