"""``sparsecast info``: what a volume holds, and how much of it a TF leaves non-empty."""

from __future__ import annotations

import time
from typing import Annotated

import numpy as np
import typer
from rich.text import Text

from ..kernel_cache import compile_note, compile_seconds
from ..storage import BrickedVolume
from .app import (
    AllowOutsideOpt, DimsOpt, DtypeOpt, FileArg, LazyOpt, LevelOpt, MemoryLimitOpt, NonFiniteOpt, OrientationOpt,
    SpacingOpt, TfOpt, TfRangeOpt, ThresholdOpt, app, out,
)
from .inputs import load_input, make_tf

__all__ = ["info", "orientation_line"]


@app.command()
def info(
    file: FileArg = None,
    tf: TfOpt = "viridis",
    tf_range: TfRangeOpt = None,
    threshold: ThresholdOpt = "auto",
    brick_size: Annotated[int, typer.Option(help="Brick edge in cells for the occupancy figure.")] = 8,
    dims: DimsOpt = None,
    dtype: DtypeOpt = None,
    spacing: SpacingOpt = None,
    orientation: OrientationOpt = None,
    lazy: LazyOpt = None,
    memory_limit: MemoryLimitOpt = None,
    level: LevelOpt = None,
    nonfinite: NonFiniteOpt = None,
    allow_outside_data: AllowOutsideOpt = False,
    presets: Annotated[bool, typer.Option("--presets", help="List TF presets and exit.")] = False,
    indices: Annotated[bool, typer.Option("--indices", help="List spatial indices and exit.")] = False,
) -> None:
    """Describe a volume: dims, dtype, spacing, value range, histogram, occupancy for a TF."""
    from ..index import available_indices
    from ..transfer import PRESETS

    if presets:
        out.print("TF presets: " + ", ".join(PRESETS))
        return
    if indices:
        from ..index import index_options

        out.print("indices: " + ", ".join(available_indices()))
        # What --index NAME:KEY=VALUE accepts (--cell is cell=).
        for name in available_indices():
            opts = index_options(name)
            listed = "any keyword" if opts is None else (", ".join(opts) or "no options")
            out.print(f"  {name:<15} {listed}")
        return
    vol = load_input(file, dims, dtype, spacing, allow_outside_data, orientation, lazy=lazy,
                     memory_limit=memory_limit, level=level, nonfinite=nonfinite)
    tfn = make_tf(tf, vol, tf_range, threshold)
    lo, hi = vol.value_range
    c0 = compile_seconds()
    bricks = vol.brick_stats(brick_size)  # its build_ms excludes first-use compilation
    t0 = time.perf_counter()
    nonempty = tfn.classify_bricks(vol, brick_size)
    classify_ms = (time.perf_counter() - t0) * 1e3
    note = compile_note(compile_seconds() - c0)
    nx, ny, nz = vol.dims
    out.print(Text.assemble((vol.name, "bold"), "  ", str(file) if file else "(built-in demo)"))
    if isinstance(vol, BrickedVolume):
        out.print(f"  dims      {nx} x {ny} x {nz}  ({vol.dense_nbytes / 2**20:.1f} MiB dense, dtype {vol.dtype})")
        out.print(f"  storage   bricks of {vol.brick_size}^3: {vol.stored_bricks} of {int(np.prod(vol.brick_grid))} "
                  f"stored ({100 * vol.stored_bricks / max(1, int(np.prod(vol.brick_grid))):.2f} %), "
                  f"{vol.resident_bricks} resident, {vol.nbytes / 2**20:.1f} MiB held"
                  + (f", memory_limit {vol.memory_limit / 2**20:.0f} MiB" if vol.memory_limit else "")
                  + (", read lazily" if vol.lazy else ""))
    else:
        out.print(f"  dims      {nx} x {ny} x {nz}  ({vol.nbytes / 2**20:.1f} MiB, dtype {vol.dtype})")
    out.print(f"  spacing   {tuple(round(float(s), 6) for s in vol.spacing)}   origin {tuple(round(float(o), 6) for o in vol.origin)}")
    out.print(f"  anatomy   {orientation_line(vol.orientation)}")
    out.print(f"  range     [{lo:g}, {hi:g}]")
    out.print(f"  histogram |{histogram_sketch(vol)}|  (log counts, {lo:g} .. {hi:g})")
    out.print(
        f"  occupancy {100 * nonempty.mean():.2f} % of {nonempty.size} bricks of {brick_size}^3 are non-empty "
        f"for TF {tfn.name!r} over [{tfn.value_range[0]:g}, {tfn.value_range[1]:g}] "
        f"(brick stats {bricks.build_ms:.1f} ms, classify {classify_ms:.3f} ms" + (f"; {note})" if note else ")")
    )
    if tfn.sampling != "trilinear" or (file is not None and vol.dtype.kind in "ui" and vol.value_range[1] < 256
                                     and _few_ids(vol)):
        out.print("  labels    " + label_summary(vol, tfn))


def _few_ids(vol, most: int = 64) -> bool:
    ids = vol.label_ids()
    return ids is not None and len(ids) <= most


def label_summary(vol, tf) -> str:
    """``N ids: id (voxels[, shown]), ...`` for a label volume (at most 24 listed)."""
    counts = vol.label_counts()
    if counts is None:
        return "none (values are not integer ids, or more than 4096 distinct values)"
    ids, n = counts
    shown = set(getattr(tf, "visible", ()))
    parts = [f"{int(i)} ({int(c)} voxels{', shown' if int(i) in shown else ''})" for i, c in zip(ids[:24], n[:24])]
    more = f", ... {len(ids) - 24} more" if len(ids) > 24 else ""
    return f"{len(ids)} ids: " + ", ".join(parts) + more


def orientation_line(codes) -> str:
    """``RAS (+i right, +j anterior, +k superior)``, or what its absence means."""
    if codes is None:
        return "no orientation in the file (--view needs one: --orientation RAS, LPS, ...)"
    names = {"L": "left", "R": "right", "A": "anterior", "P": "posterior", "S": "superior", "I": "inferior"}
    return f"{''.join(codes)} (" + ", ".join(f"+{a} {names[c]}" for a, c in zip("ijk", codes)) + ")"


def histogram_sketch(vol, bins: int = 48) -> str:
    """One line of block characters: log-scaled histogram of the voxel values."""
    counts, _ = vol.histogram(bins)
    levels = " ▁▂▃▄▅▆▇█"
    logc = np.log1p(counts.astype(np.float64))
    top = logc.max() or 1.0
    return "".join(levels[int(round(v / top * (len(levels) - 1)))] for v in logc)
