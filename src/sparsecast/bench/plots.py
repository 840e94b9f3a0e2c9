"""Figures in the style of the papers, drawn from benchmark records (matplotlib, PNG).

All figures use the sparse TF and, per dataset, its largest image size in the records.

- ``frame_times.png``: frame ms per structure and dataset (median over views),
  log scale, with the naive marcher and each peer as lines (hybrid-grids paper, Fig. 3).
- ``build_times.png``: cold build, TF rebuild and frame ms per structure and dataset
  (construction next to rendering, k-d tree paper Table 1).
- ``build_vs_render.png``: per volume size of the n-body family, rebuild ms stacked
  under frame ms for each structure (LBVH paper, Fig. 4), when present.
- ``peer_images.png``: our image next to each peer's on the same case, with the
  PSNR (a person's check that the cases match), when peers ran with ``--images``.
- ``sweep_<family>.png``: speed-up over naive along a synthetic sweep
  (``fig5a-*``, ``fig5b-*`` datasets; hybrid-grids paper, Fig. 5), when present.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from .._util.atomic import atomic_path
from .summary import SWEEP, build_ms, render_rows

__all__ = ["write_plots"]

#: the n-body field at growing sizes (LBVH paper Fig. 4 style), smallest first
_SCALE_FAMILY = ("demo-128", "demo", "demo-512")
_PEER_COLORS = ("tab:green", "tab:purple", "tab:brown")


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
    rows = [r for r in render_rows(records) if r.tf == "default"]
    largest: dict[str, int] = {}
    for r in rows:
        largest[r.dataset] = max(largest.get(r.dataset, 0), r.width or 0)
    rows = [r for r in rows if (r.width or 0) == largest[r.dataset]]
    sizes = sorted({r.size for r in rows if r.width})
    size_note = f", {' / '.join(sizes)}" if sizes else ""
    frame = {(r.dataset, r.method): r.ms for r in rows if not r.peer}
    peer_ms = {(r.dataset, r.method): r.ms for r in rows if r.peer}
    peers = sorted({m for _, m in peer_ms})
    datasets = list(dict.fromkeys(d for d, _ in frame if not SWEEP.match(d)))
    methods = list(dict.fromkeys(m for _, m in frame if m != "naive"))
    builds = build_ms(records)

    def grid(n: int):
        cols = min(n, 4)
        rows_ = -(-n // cols)
        fig, axes = plt.subplots(rows_, cols, figsize=(4.2 * cols, 3.8 * rows_), squeeze=False)
        for ax in axes.flat[n:]:
            ax.set_visible(False)
        return fig, list(axes.flat[:n])

    if datasets and methods:
        fig, axes = grid(len(datasets))
        for ax, ds in zip(axes, datasets):
            ms = [frame.get((ds, m), float("nan")) for m in methods]
            ax.bar(range(len(methods)), ms, color="tab:blue", label="frame (ours)")
            if (ds, "naive") in frame:
                ax.axhline(frame[(ds, "naive")], color="tab:red", lw=1.5, label="naive")
            for p, color in zip(peers, _PEER_COLORS):
                if (ds, p) in peer_ms:
                    ax.axhline(peer_ms[(ds, p)], color=color, lw=1.5, ls="--", label=p)
            ax.set_yscale("log")
            ax.set_xticks(range(len(methods)), methods, rotation=45, ha="right", fontsize=8)
            ax.set_title(ds, fontsize=10)
            ax.set_ylabel("frame ms (median over views)", fontsize=8)
        _shared_legend(fig, axes)
        fig.suptitle(f"Frame time per structure (sparse TF{size_note})")
        fig.tight_layout(rect=(0, 0.06, 1, 1))
        written.append(_save(fig, out / "frame_times.png"))
        plt.close(fig)

        fig, axes = grid(len(datasets))
        for ax, ds in zip(axes, datasets):
            x = range(len(methods))
            cold = [builds.get((ds, "default", m, "build_cold"), {}).get("ms") or 0.0 for m in methods]
            rebuild = [builds.get((ds, "default", m, "rebuild"), {}).get("ms") or 0.0 for m in methods]
            render_ms = [frame.get((ds, m), 0.0) for m in methods]
            ax.bar([i - 0.27 for i in x], cold, width=0.27, label="first build")
            ax.bar(x, rebuild, width=0.27, label="rebuild (TF change)")
            ax.bar([i + 0.27 for i in x], render_ms, width=0.27, label="frame")
            ax.set_yscale("log")
            ax.set_xticks(list(x), methods, rotation=45, ha="right", fontsize=8)
            ax.set_title(ds, fontsize=10)
            ax.set_ylabel("ms", fontsize=8)
        _shared_legend(fig, axes)
        fig.suptitle(f"Construction vs rendering (sparse TF{size_note})")
        fig.tight_layout(rect=(0, 0.06, 1, 1))
        written.append(_save(fig, out / "build_times.png"))
        plt.close(fig)

    family = [d for d in _SCALE_FAMILY if d in datasets]
    if len(family) >= 2 and methods:
        fig, axes = plt.subplots(1, len(family), figsize=(4.4 * len(family), 3.8), squeeze=False, sharey=True)
        for ax, ds in zip(axes[0], family):
            x = range(len(methods))
            rebuild = [builds.get((ds, "default", m, "rebuild"), {}).get("ms") or 0.0 for m in methods]
            render_ms = [frame.get((ds, m), 0.0) for m in methods]
            ax.bar(x, rebuild, color="tab:orange", label="rebuild (TF change)")
            ax.bar(x, render_ms, bottom=rebuild, color="tab:blue", label="frame")
            if (ds, "naive") in frame:
                ax.axhline(frame[(ds, "naive")], color="tab:red", lw=1.5, label="naive frame")
            dims = next((r.get("dims") for r in records if r.get("phase") == "load" and r["dataset"] == ds), None)
            ax.set_title(f"{ds} ({'x'.join(map(str, dims))})" if dims else ds, fontsize=10)
            ax.set_xticks(list(x), methods, rotation=45, ha="right", fontsize=8)
        axes[0][0].set_ylabel("ms (rebuild + one frame)")
        _shared_legend(fig, list(axes[0]))
        fig.suptitle(f"Build vs render per volume size (n-body field, sparse TF{size_note})")
        fig.tight_layout(rect=(0, 0.08, 1, 1))
        written.append(_save(fig, out / "build_vs_render.png"))
        plt.close(fig)

    path = _peer_images(records, out / "peer_images.png", plt)
    if path is not None:
        written.append(path)

    families: dict[str, dict[str, list[tuple[int, float]]]] = defaultdict(lambda: defaultdict(list))
    for (ds, m), ms in frame.items():
        match = SWEEP.match(ds)
        if match and m != "naive" and (ds, "naive") in frame:
            families[match.group(1)][m].append((int(match.group(2)), frame[(ds, "naive")] / ms))
    for fam, per_method in sorted(families.items()):
        fig, ax = plt.subplots(figsize=(5.5, 3.6))
        for m, pts in sorted(per_method.items()):
            pts.sort()
            ax.plot([p for p, _ in pts], [s for _, s in pts], marker="o", label=m)
        ax.axhline(1.0, color="tab:red", lw=1, label="naive")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("cluster radius (% of edge)" if fam.startswith("fig5a") else "number of clusters")
        ax.set_ylabel("speed-up over naive")
        ax.set_title(fam)
        ax.legend(fontsize=8)
        written.append(_save(fig, out / f"sweep_{fam}.png"))
        plt.close(fig)
    return written


def _peer_images(records: list[dict[str, Any]], path: Path, plt) -> Path | None:
    """Our image next to each peer's on the same case (sparse TF, smallest size, first
    view), one row per dataset, titled with frame ms and the PSNR against ours."""
    from PIL import Image as PILImage

    shots = [r for r in records if r.get("phase") == "render" and r.get("image") and r.get("tf") == "default"
             and Path(r["image"]).is_file()]
    peers = sorted({r["method"] for r in shots if r.get("peer")})
    if not peers:
        return None
    cases: dict[tuple, dict[str, dict[str, Any]]] = defaultdict(dict)
    for r in shots:
        cases[(r["dataset"], r["width"], r["height"], r["view"])][r["method"] if r.get("peer") else "ours"] = r
    rows: dict[str, tuple] = {}
    for (ds, w, h, view), shot in cases.items():
        if "ours" in shot and len(shot) > 1 and (ds not in rows or w * h < rows[ds][1] * rows[ds][2]):
            rows[ds] = (ds, w, h, view)
    if not rows:
        return None
    columns = ["ours"] + peers
    fig, axes = plt.subplots(len(rows), len(columns), figsize=(2.6 * len(columns), 2.8 * len(rows)), squeeze=False)
    for ax_row, key in zip(axes, rows.values()):
        shot = cases[key]
        for ax, name in zip(ax_row, columns):
            ax.set_axis_off()
            if name not in shot:
                continue
            r = shot[name]
            with PILImage.open(r["image"]) as im:
                im.thumbnail((256, 256))
                ax.imshow(np.asarray(im.convert("RGB")))
            label = "sparsecast (naive)" if name == "ours" else name
            note = f"{r['ms']:.0f} ms" if name == "ours" else f"{r['ms']:.0f} ms, {r.get('psnr_vs_naive', 0):.1f} dB"
            ax.set_title(f"{key[0]} {key[1]}x{key[2]}\n{label}: {note}", fontsize=7)
    fig.suptitle("The same case rendered by sparsecast and the peers (PSNR against ours)", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=80, bbox_inches="tight")
    plt.close(fig)
    return path


def _shared_legend(fig, axes) -> None:
    """One legend for the figure: every label drawn in any panel, once."""
    labels: dict[str, Any] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            labels.setdefault(label, handle)
    fig.legend(list(labels.values()), list(labels), loc="lower center", ncol=min(len(labels), 6), fontsize=8)
