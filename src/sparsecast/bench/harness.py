"""Timing: warm-up excluded, median of N runs, one JSON-able record per measurement."""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..camera import Camera
from ..index import available_indices, build_index
from ..renderers import render
from ..errors import ParameterError
from ..transfer import TransferFunction
from ..volume import Volume
from .datasets import DATASETS
from .irt import irt_build_times
from .timing import median_ms

__all__ = ["BenchConfig", "run_benchmarks", "machine_info", "parse_method", "dense_tf"]


@dataclass
class BenchConfig:
    """What ``sparsecast bench`` runs.

    Attributes
    ----------
    datasets : list of str
        Names from :data:`DATASETS`; unavailable ones (no shared data) are skipped.
    methods : list of str
        Index names (see :func:`available_indices`), optionally with build options
        as ``name:key=value,...`` (e.g. ``grid-pc:cell=8``).
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
    dense_tf : bool
        Also run every method with a TF that leaves no empty space.
    irt : bool
        Also time iterative-range-tree builds and queries on TF tables of 256-4096
        entries against the prefix-count query.
    """

    datasets: list[str] = field(default_factory=lambda: [n for n, d in DATASETS.items() if d.default])
    methods: list[str] = field(default_factory=available_indices)
    width: int = 512
    height: int = 512
    views: list[tuple[float, float]] = field(default_factory=lambda: [(30.0, 20.0), (0.0, 0.0)])
    projection: str = "perspective"
    repeat: int = 5
    warmup: int = 1
    dt: float | None = None
    dense_tf: bool = True
    irt: bool = True


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


_LITERALS = {"none": None, "true": True, "false": False}


def parse_method(spec: str) -> tuple[str, dict[str, Any]]:
    """``"grid-pc:cell=8"`` -> ``("grid-pc", {"cell": 8})``.

    Values are parsed as None/True/False, int, float, or else kept as strings.
    """
    name, _, opts = spec.partition(":")
    options: dict[str, Any] = {}
    for item in filter(None, opts.split(",")):
        key, eq, value = item.partition("=")
        if not eq:
            raise ParameterError(f"method {spec!r}: expected name:key=value[,key=value], got {item!r}")
        if value.lower() in _LITERALS:
            options[key] = _LITERALS[value.lower()]
            continue
        for conv in (int, float):
            try:
                options[key] = conv(value)
                break
            except ValueError:
                continue
        else:
            options[key] = value
    if name not in available_indices():
        raise ParameterError(f"method {spec!r}: unknown index {name!r}; expected one of {', '.join(available_indices())}")
    return name, options


def run_benchmarks(
    config: BenchConfig,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """Run every case of ``config`` and return the records.

    Phases recorded per dataset: ``load``, ``brick_stats`` (per-volume min/max,
    B = 8, from scratch), ``tf_classify`` (re-classifying every brick for the TF).
    Per TF (the dataset's own, and ``dense``: non-zero opacity everywhere, to show
    what skipping costs when there is nothing to skip) and method:
    ``build_cold`` (first build on a volume, per-volume precomputation included),
    ``rebuild`` (what a TF edit costs), and one ``render`` per view with samples
    taken and the oracle count of samples in non-empty space.
    """
    say = progress or (lambda msg: None)
    machine = machine_info()
    records: list[dict[str, Any]] = []
    methods = [(spec, *parse_method(spec)) for spec in config.methods]
    _warm_up_kernels([(name, opts) for _, name, opts in methods])

    def record(**kw) -> None:
        rec = {
            "dataset": None, "tf": None, "method": None, "phase": None, "view": None, "ms": None,
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
        fresh = iter([Volume(vol.data, vol.spacing, vol.origin) for _ in range(config.repeat)])
        ms, runs, stats = median_ms(lambda: next(fresh).brick_stats(8), config.repeat, 0)
        record(dataset=ds_name, phase="brick_stats", ms=ms, ms_runs=runs, bytes=stats.nbytes)
        bricks = vol.brick_stats(8)
        tfs = {"default": ds.make_tf(vol)}
        if config.dense_tf:
            tfs["dense"] = dense_tf(vol)
        for tf_name, tf in tfs.items():
            ms, runs, nonempty = median_ms(lambda: tf.classify(bricks.vmin, bricks.vmax), config.repeat, 1)
            record(dataset=ds_name, tf=tf_name, phase="tf_classify", ms=ms, ms_runs=runs,
                   occupancy=float(np.mean(nonempty)), bricks=int(nonempty.size))

            for spec, method, opts in methods:
                say(f"{ds_name}/{tf_name}: {spec} build")
                # A fresh Volume object per run: no cached brick statistics.
                fresh = iter([Volume(vol.data, vol.spacing, vol.origin) for _ in range(config.repeat)])
                ms, runs, index = median_ms(lambda: build_index(next(fresh), tf, method, **opts),
                                             config.repeat, 0)
                record(dataset=ds_name, tf=tf_name, method=spec, phase="build_cold", ms=ms, ms_runs=runs,
                       bytes=index.stats()["bytes"])
                ms, runs, index = median_ms(lambda: build_index(vol, tf, method, **opts),
                                             config.repeat, config.warmup)
                record(dataset=ds_name, tf=tf_name, method=spec, phase="rebuild", ms=ms, ms_runs=runs,
                       bytes=index.stats()["bytes"], index_stats=index.stats())
                for az, el in config.views:
                    view = f"az{az:g}_el{el:g}"
                    say(f"{ds_name}/{tf_name}: {spec} render {view}")
                    cam = Camera.orbit(vol, az, el, projection=config.projection)  # type: ignore[arg-type]
                    ms, runs, img = median_ms(
                        lambda: render(vol, tf, cam, config.width, config.height, dt=config.dt, index=index),
                        config.repeat, config.warmup,
                    )
                    record(dataset=ds_name, tf=tf_name, method=spec, phase="render", view=view, ms=ms,
                           ms_runs=runs, samples=img.stats["samples"],
                           samples_nonempty=img.stats["samples_nonempty"],
                           bytes=index.stats()["bytes"], width=config.width, height=config.height,
                           dt=img.stats["dt"])
    if config.irt:
        say("transfer-function range trees")
        for rec in irt_build_times(repeat=max(config.repeat, 5)):
            record(dataset="tf-table", **rec)
    _add_ratios(records)
    return records


def dense_tf(vol: Volume) -> TransferFunction:
    """A TF with non-zero opacity for every value: no empty space at all."""
    lo, hi = vol.value_range
    if hi <= lo:
        hi = lo + 1.0
    return TransferFunction([(lo, 0.2, 0.3, 0.8, 0.004), (hi, 1.0, 0.9, 0.6, 0.2)], (lo, hi), name="dense")


def _warm_up_kernels(methods: list[tuple[str, dict[str, Any]]]) -> None:
    """Compile (or load from cache) every kernel on a tiny volume, outside all timings."""
    from ..datasets import nbody_blobs

    for dtype in (np.float32, np.uint8):
        small = nbody_blobs(16, n_clusters=2, blobs_per_cluster=4, dtype=dtype)
        tf = TransferFunction.preset("viridis", small.value_range)
        cam = Camera.orbit(small)
        small.brick_stats(8)
        tf.classify(small.brick_stats(8).vmin, small.brick_stats(8).vmax)
        for name, opts in methods:
            render(small, tf, cam, 8, 8, index=name, **opts)


def _add_ratios(records: Iterable[dict[str, Any]]) -> None:
    """``speedup_vs_naive`` for every render record with a naive twin in the same run,
    and ``samples_vs_oracle`` (samples taken / samples in non-empty space)."""
    recs = list(records)
    naive = {(r["dataset"], r["tf"], r["view"]): r["ms"] for r in recs
             if r["phase"] == "render" and r["method"] == "naive"}
    for r in recs:
        if r["phase"] != "render":
            continue
        base = naive.get((r["dataset"], r["tf"], r["view"]))
        r["speedup_vs_naive"] = base / r["ms"] if base and r["ms"] else None
        r["msamples_per_s"] = r["samples"] / r["ms"] / 1e3 if r["ms"] else None
        ne = r["samples_nonempty"]
        r["samples_vs_oracle"] = r["samples"] / ne if ne else None
