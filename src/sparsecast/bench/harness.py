"""Timing: warm-up excluded, median of N runs, one JSON-able record per measurement."""

from __future__ import annotations

import os
import platform
import statistics
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..camera import Camera
from ..index import available_indices, build_index
from ..renderers import render
from ..volume import Volume
from .datasets import DATASETS

__all__ = ["BenchConfig", "run_benchmarks", "machine_info"]


@dataclass
class BenchConfig:
    """What ``sparsecast bench`` runs.

    Attributes
    ----------
    datasets : list of str
        Names from :data:`DATASETS`; unavailable ones (no shared data) are skipped.
    methods : list of str
        Index names (see :func:`available_indices`).
    width, height : int
        Image size.
    views : list of (azimuth, elevation)
        Orbit views, in degrees.
    projection : str
    repeat : int
        Timed runs per measurement (the median is reported).
    warmup : int
        Untimed runs before timing (JIT compilation, caches).
    dt : float or None
        Sampling step (default: half the smallest spacing).
    """

    datasets: list[str] = field(default_factory=lambda: list(DATASETS))
    methods: list[str] = field(default_factory=available_indices)
    width: int = 512
    height: int = 512
    views: list[tuple[float, float]] = field(default_factory=lambda: [(30.0, 20.0), (0.0, 0.0)])
    projection: str = "perspective"
    repeat: int = 5
    warmup: int = 1
    dt: float | None = None


def machine_info() -> dict[str, Any]:
    """Where the numbers come from (attached to every record)."""
    import numba

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "numba_threads": numba.get_num_threads(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
    }


def _median_ms(fn: Callable[[], Any], repeat: int, warmup: int) -> tuple[float, list[float], Any]:
    result = None
    for _ in range(warmup):
        result = fn()
    times = []
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        result = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), times, result


def run_benchmarks(
    config: BenchConfig,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """Run every case of ``config`` and return the records.

    Phases recorded per dataset: ``load``, ``brick_stats`` (per-volume min/max,
    B = 8), ``tf_classify`` (re-classifying every brick for the TF: what a TF edit
    costs before any index build); per method: ``build`` and one ``render`` per
    view, with samples taken and the oracle count of samples in non-empty space.
    """
    say = progress or (lambda msg: None)
    machine = machine_info()
    records: list[dict[str, Any]] = []
    _warm_up_kernels()

    def record(**kw) -> None:
        rec = {
            "dataset": None, "method": None, "phase": None, "view": None, "ms": None,
            "ms_runs": None, "samples": None, "samples_nonempty": None, "bytes": None,
            "width": None, "height": None, "dt": None,
        }
        rec.update(kw)
        rec["machine"] = machine
        records.append(rec)

    for ds_name in config.datasets:
        ds = DATASETS[ds_name]
        if not ds.available():
            say(f"skip {ds_name}: data not found")
            continue
        say(f"{ds_name}: loading")
        t0 = time.perf_counter()
        vol = ds.load()
        record(dataset=ds_name, phase="load", ms=(time.perf_counter() - t0) * 1e3, bytes=vol.nbytes)

        say(f"{ds_name}: brick statistics")
        ms, runs, stats = _median_ms(
            lambda: Volume(vol.data, vol.spacing, vol.origin).brick_stats(8), config.repeat, 0
        )
        record(dataset=ds_name, phase="brick_stats", ms=ms, ms_runs=runs, bytes=stats.nbytes)
        bricks = vol.brick_stats(8)
        tf = ds.make_tf(vol)
        ms, runs, nonempty = _median_ms(lambda: tf.classify(bricks.vmin, bricks.vmax), config.repeat, 1)
        record(dataset=ds_name, phase="tf_classify", ms=ms, ms_runs=runs,
               occupancy=float(np.mean(nonempty)), bricks=int(nonempty.size))

        for method in config.methods:
            say(f"{ds_name}: {method} build")
            ms, runs, index = _median_ms(lambda: build_index(vol, tf, method), config.repeat, config.warmup)
            record(dataset=ds_name, method=method, phase="build", ms=ms, ms_runs=runs,
                   bytes=index.stats()["bytes"], index_stats=index.stats())
            for az, el in config.views:
                view = f"az{az:g}_el{el:g}"
                say(f"{ds_name}: {method} render {view}")
                cam = Camera.orbit(vol, az, el, projection=config.projection)  # type: ignore[arg-type]
                ms, runs, img = _median_ms(
                    lambda: render(vol, tf, cam, config.width, config.height, dt=config.dt, index=index),
                    config.repeat, config.warmup,
                )
                record(dataset=ds_name, method=method, phase="render", view=view, ms=ms, ms_runs=runs,
                       samples=img.stats["samples"], samples_nonempty=img.stats["samples_nonempty"],
                       bytes=index.stats()["bytes"], width=config.width, height=config.height,
                       dt=img.stats["dt"])
    _add_ratios(records)
    return records


def _warm_up_kernels() -> None:
    """Compile (or load from cache) every kernel on a tiny volume, outside all timings."""
    from ..datasets import nbody_blobs
    from ..transfer import TransferFunction

    small = nbody_blobs(16, n_clusters=2, blobs_per_cluster=4)
    tf = TransferFunction.preset("viridis", small.value_range)
    cam = Camera.orbit(small)
    small.brick_stats(8)
    for name in available_indices():
        render(small, tf, cam, 8, 8, index=name)


def _add_ratios(records: Iterable[dict[str, Any]]) -> None:
    """``speedup_vs_naive`` for every render record with a naive twin in the same run,
    and ``samples_vs_oracle`` (samples taken / samples in non-empty space)."""
    recs = list(records)
    naive = {(r["dataset"], r["view"]): r["ms"] for r in recs
             if r["phase"] == "render" and r["method"] == "naive"}
    for r in recs:
        if r["phase"] != "render":
            continue
        base = naive.get((r["dataset"], r["view"]))
        r["speedup_vs_naive"] = base / r["ms"] if base and r["ms"] else None
        r["msamples_per_s"] = r["samples"] / r["ms"] / 1e3 if r["ms"] else None
        ne = r["samples_nonempty"]
        r["samples_vs_oracle"] = r["samples"] / ne if ne else None
