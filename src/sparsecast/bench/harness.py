"""The benchmark runner: datasets x TFs x methods x image sizes x views, then peers and sections.

One record per measurement (warm-up excluded, median of N). Records go to a
:class:`~sparsecast.bench.progress.ResultStore` as they are taken, so a long run
can be interrupted and resumed: finished cases are skipped, not re-measured.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import platform
import time
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..camera import Camera
from ..cli.parse import parse_index_spec
from ..index import available_indices, build_index
from ..renderers import render
from ..transfer import TransferFunction
from ..volume import Volume
from .catalog import DATASETS
from .images import image_name, psnr, save_png
from .irt import irt_build_times
from .peers import PeerUnavailable, load_peer
from .progress import Progress, ResultStore
from .suites import Suite, view_name
from .timing import median_ms

__all__ = ["BenchConfig", "run_benchmarks", "finished_records", "machine_info", "dense_tf",
           "add_ratios"]


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
    sizes : list of (width, height)
        Image sizes.
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
    peers : list of str
        Peer renderers (``vtk``, ``yt``) run on the same cases; missing ones are skipped.
    dense_views : int or None
        The dense TF renders only the first this many views (None: all): with no
        empty space every index costs about a naive frame, and a few views show it.
    peer_views : int
        Peers render the first this many views (they are much slower than the indices).
    sections : list of str
        ``sparsecast.bench.<name>`` modules whose ``run(...)`` adds their own tables.
    images_dir : path or None
        Where to save our (naive) image and each peer's image of the first view per
        size, for a person to compare.
    """

    datasets: list[str] = field(default_factory=lambda: [n for n, d in DATASETS.items() if d.default])
    methods: list[str] = field(default_factory=available_indices)
    sizes: list[tuple[int, int]] = field(default_factory=lambda: [(512, 512)])
    views: list[tuple[float, float]] = field(default_factory=lambda: [(30.0, 20.0), (0.0, 0.0)])
    projection: str = "perspective"
    repeat: int = 5
    warmup: int = 1
    dt: float | None = None
    dense_tf: bool = True
    irt: bool = True
    peers: list[str] = field(default_factory=list)
    dense_views: int | None = None
    peer_views: int = 2
    sections: list[str] = field(default_factory=list)
    images_dir: Path | None = None

    @classmethod
    def from_suite(cls, suite: Suite, **overrides: Any) -> "BenchConfig":
        """The config of ``suite``; keyword arguments that are not None replace its fields."""
        cfg = cls(
            datasets=suite.dataset_names(),
            methods=suite.method_specs(),
            sizes=list(suite.sizes), views=list(suite.views), repeat=suite.repeat, warmup=suite.warmup,
            dense_tf=suite.dense_tf, dense_views=suite.dense_views, peer_views=suite.peer_views,
            irt=suite.irt, peers=list(suite.peers), sections=list(suite.sections),
        )
        for key, value in overrides.items():
            if value is not None:
                setattr(cfg, key, value)
        return cfg


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


Record = dict[str, Any]
_BLANK: Record = {
    "dataset": None, "tf": None, "method": None, "phase": None, "view": None, "ms": None,
    "ms_runs": None, "samples": None, "samples_nonempty": None, "bytes": None,
    "width": None, "height": None, "dt": None,
}


def run_benchmarks(
    config: BenchConfig,
    progress: Progress | Callable[[str], None] | None = None,
    store: ResultStore | None = None,
) -> list[Record]:
    """Run every case of ``config`` not yet in ``store`` and return all records.

    Phases recorded per dataset: ``load``, ``brick_stats`` (per-volume min/max,
    B = 8, from scratch), ``tf_classify`` (re-classifying every brick for the TF).
    Per TF (the dataset's own, and ``dense``: non-zero opacity everywhere, to show
    what skipping costs when there is nothing to skip) and method:
    ``build_cold`` (first build on a volume, per-volume precomputation included),
    ``rebuild`` (what a TF edit costs), and one ``render`` per image size and view
    with samples taken, the oracle count of samples in non-empty space and, for
    approximate indices, the PSNR against the naive image. Then one ``render`` per
    peer, size and view (PSNR against our naive image), the sections (``irt``,
    ``bih``, ``surface``...), and finally the ratios of :func:`add_ratios`.

    Parameters
    ----------
    config : BenchConfig
    progress : Progress or callable, optional
        Told about each case (a callable receives one message string per step).
    store : ResultStore, optional
        Where records go as they are taken; cases whose key it already holds are
        skipped (a resumed run). Default: in memory only.
    """
    store = store if store is not None else ResultStore()
    run = _Run(config, store, progress)
    run.all()
    return finished_records(store)


def finished_records(store: ResultStore) -> list[Record]:
    """The records ``store`` holds so far, with their ratios (also after an interrupt)."""
    records = [r for r in store.records if r.get("phase") != "section_done"]  # journal bookkeeping
    add_ratios(records)
    return records


class _CallbackProgress(Progress):
    """A :class:`Progress` that forwards its line to a callable (the old interface)."""

    def __init__(self, say: Callable[[str], None]) -> None:
        super().__init__(0)
        self._callback = say

    def say(self, message: str) -> None:
        super().say(message)
        self._callback(self._line())


class _Run:
    """One pass over a config: the plan of case keys, then the measurements."""

    def __init__(self, config: BenchConfig, store: ResultStore,
                 progress: Progress | Callable[[str], None] | None) -> None:
        self.cfg = config
        self.store = store
        self.machine = machine_info()
        if progress is None:
            progress = Progress(0)
        elif not isinstance(progress, Progress):
            progress = _CallbackProgress(progress)
        self.progress = progress
        self.methods = [(spec, *parse_index_spec(spec)) for spec in config.methods]
        self.peers = self._available_peers()
        self.sections = self._available_sections()
        self.datasets = []
        for name in config.datasets:
            if DATASETS[name].available():
                self.datasets.append(name)
            else:
                self.skip(name, "dataset", "data not found (no shared data folder or file)")
        self.tf_names = ["default"] + (["dense"] if config.dense_tf else [])
        keys = self._plan()
        self.progress.total = len(keys)
        self.progress.done_count = sum(store.done(**k) for k in keys)

    # -- bookkeeping ---------------------------------------------------------
    def record(self, **kw: Any) -> Record:
        rec = {**_BLANK, **kw, "machine": self.machine}
        self.store.add(rec)
        self.progress.advance()
        return rec

    def skip(self, what: str, kind: str, reason: str) -> None:
        """A note in the results (not the journal: a later run retries it)."""
        self.store.note({**_BLANK, "method": what, "phase": "skipped", "kind": kind,
                         "reason": reason, "machine": self.machine})
        self.progress.say(f"skip {what}: {reason}")

    def _available_peers(self) -> list[tuple[str, Any]]:
        out = []
        for name in self.cfg.peers:
            try:
                out.append((name, load_peer(name)))
            except PeerUnavailable as exc:
                self.skip(name, "peer", str(exc))
            except Exception as exc:  # a broken install must not end a long run
                self.skip(name, "peer", f"failed to load: {type(exc).__name__}: {exc}")
        return out

    def _available_sections(self) -> list[str]:
        out = []
        for name in self.cfg.sections:
            if name == "irt" or importlib.util.find_spec(f"{__package__}.{name}") is not None:
                out.append(name)
            else:
                self.skip(name, "section", f"module sparsecast.bench.{name} is not there yet")
        if self.cfg.irt and "irt" not in out:
            out.insert(0, "irt")
        return out

    def views(self, tf: str, peer: bool = False) -> list[tuple[float, float]]:
        """The views rendered for TF ``tf`` (by our methods, or by the peers)."""
        views = self.cfg.views
        if tf == "dense" and self.cfg.dense_views is not None:
            views = views[: self.cfg.dense_views]
        return views[: self.cfg.peer_views] if peer else views

    def render_keys(self, ds: str, tf: str, method: str, peer: bool = False) -> list[dict[str, Any]]:
        return [dict(dataset=ds, tf=tf, method=method, width=w, height=h, view=view_name(v), phase="render")
                for w, h in self.cfg.sizes for v in self.views(tf, peer)]

    def method_keys(self, ds: str, tf: str, spec: str) -> list[dict[str, Any]]:
        return ([dict(dataset=ds, tf=tf, method=spec, phase=p) for p in ("build_cold", "rebuild")]
                + self.render_keys(ds, tf, spec))

    def tf_keys(self, ds: str, tf: str) -> list[dict[str, Any]]:
        keys = [dict(dataset=ds, tf=tf, phase="tf_classify")]
        for spec, _, _ in self.methods:
            keys += self.method_keys(ds, tf, spec)
        for peer, _ in self.peers:
            keys += self.render_keys(ds, tf, peer, peer=True)
        return keys

    def dataset_keys(self, ds: str) -> list[dict[str, Any]]:
        keys = [dict(dataset=ds, phase=p) for p in ("load", "brick_stats")]
        for tf in self.tf_names:
            keys += self.tf_keys(ds, tf)
        return keys

    def _plan(self) -> list[dict[str, Any]]:
        keys = [k for ds in self.datasets for k in self.dataset_keys(ds)]
        return keys + [dict(method=s, phase="section_done") for s in self.sections]

    def all_done(self, keys: Iterable[dict[str, Any]]) -> bool:
        return all(self.store.done(**k) for k in keys)

    # -- the measurements ------------------------------------------------------
    def all(self) -> None:
        if any(not self.all_done(self.dataset_keys(ds)) for ds in self.datasets):
            _warm_up_kernels([(name, opts) for _, name, opts in self.methods])
        for ds in self.datasets:
            if self.all_done(self.dataset_keys(ds)):
                continue
            self.dataset(ds)
        for name in self.sections:
            if not self.store.done(method=name, phase="section_done"):
                self.section(name)

    def dataset(self, ds_name: str) -> None:
        cfg, say = self.cfg, self.progress.say
        ds = DATASETS[ds_name]
        say(f"{ds_name}: loading")
        t0 = time.perf_counter()
        vol = ds.load()
        if not self.store.done(dataset=ds_name, phase="load"):
            self.record(dataset=ds_name, phase="load", ms=(time.perf_counter() - t0) * 1e3, bytes=vol.nbytes,
                        dims=list(vol.dims), dtype=str(vol.dtype))
        if not self.store.done(dataset=ds_name, phase="brick_stats"):
            say(f"{ds_name}: brick statistics")
            fresh = iter([Volume(vol.data, vol.spacing, vol.origin) for _ in range(cfg.repeat)])
            ms, runs, stats = median_ms(lambda: next(fresh).brick_stats(8), cfg.repeat, 0)
            self.record(dataset=ds_name, phase="brick_stats", ms=ms, ms_runs=runs, bytes=stats.nbytes)
        tfs = {"default": ds.make_tf(vol)}
        if cfg.dense_tf:
            tfs["dense"] = dense_tf(vol)
        for tf_name, tf in tfs.items():
            if not self.all_done(self.tf_keys(ds_name, tf_name)):
                _TfCases(self, ds_name, vol, tf_name, tf).run()

    def section(self, name: str) -> None:
        """Run a section module (or the built-in ``irt``) and journal its records at once:
        a section interrupted half-way runs again in full."""
        self.progress.say(f"section {name}")
        recs: list[Record] = []

        def record(**kw: Any) -> None:
            recs.append({**_BLANK, **kw, "section": name, "machine": self.machine})

        cfg = self.cfg
        try:
            if name == "irt":
                for rec in irt_build_times(repeat=max(cfg.repeat, 5)):
                    record(dataset="tf-table", **rec)
            else:
                module = importlib.import_module(f"{__package__}.{name}")
                w, h = cfg.sizes[0]
                module.run(None, width=w, height=h, repeat=cfg.repeat, warmup=max(cfg.warmup, 1), record=record)
        except Exception as exc:  # one broken section must not end a long run
            last = traceback.extract_tb(exc.__traceback__)[-1]
            self.skip(name, "section", f"failed: {type(exc).__name__}: {exc} ({Path(last.filename).name}:{last.lineno})")
            return
        self.store.add_many(recs + [{**_BLANK, "method": name, "phase": "section_done", "machine": self.machine}])
        self.progress.advance()


class _TfCases:
    """Every method and peer on one (dataset, TF), sharing the naive reference images."""

    def __init__(self, run: _Run, ds_name: str, vol: Volume, tf_name: str, tf: TransferFunction) -> None:
        self.runner, self.ds, self.vol, self.tf_name, self.tf = run, ds_name, vol, tf_name, tf
        self.cfg = run.cfg
        self.dt = self.cfg.dt if self.cfg.dt is not None else 0.5 * float(vol.spacing.min())
        # (width, height, view) -> naive premultiplied RGB (float16 halves the memory of
        # 1024^2 references; plenty for a PSNR).
        self._reference: dict[tuple[int, int, str], np.ndarray] = {}

    def camera(self, view: tuple[float, float]) -> Camera:
        return Camera.orbit(self.vol, *view, projection=self.cfg.projection)  # type: ignore[arg-type]

    def reference(self, w: int, h: int, view: tuple[float, float]) -> np.ndarray:
        """Our naive image of this case (rendered untimed unless this run already has it)."""
        key = (w, h, view_name(view))
        if key not in self._reference:
            img = render(self.vol, self.tf, self.camera(view), w, h, dt=self.dt, index="naive")
            self._reference[key] = img.rgba[..., :3].astype(np.float16)
        return self._reference[key]

    def run(self) -> None:
        run, ds, tf_name = self.runner, self.ds, self.tf_name
        store = run.store
        if not store.done(dataset=ds, tf=tf_name, phase="tf_classify"):
            bricks = self.vol.brick_stats(8)
            ms, runs, nonempty = median_ms(lambda: self.tf.classify(bricks.vmin, bricks.vmax), self.cfg.repeat, 1)
            run.record(dataset=ds, tf=tf_name, phase="tf_classify", ms=ms, ms_runs=runs,
                       occupancy=float(np.mean(nonempty)), bricks=int(nonempty.size))
        for spec, method, opts in run.methods:
            if not run.all_done(run.method_keys(ds, tf_name, spec)):
                self.method(spec, method, opts)
        for peer, module in run.peers:
            if not run.all_done(run.render_keys(ds, tf_name, peer, peer=True)):
                self.peer(peer, module)

    def method(self, spec: str, method: str, opts: dict[str, Any]) -> None:
        run, cfg, ds, tf_name, vol, tf = self.runner, self.cfg, self.ds, self.tf_name, self.vol, self.tf
        say, store = run.progress.say, run.store
        say(f"{ds}/{tf_name}: {spec} build")
        if not store.done(dataset=ds, tf=tf_name, method=spec, phase="build_cold"):
            # A fresh Volume object per run: no cached brick statistics.
            fresh = iter([Volume(vol.data, vol.spacing, vol.origin) for _ in range(cfg.repeat)])
            ms, runs, index = median_ms(lambda: build_index(next(fresh), tf, method, **opts), cfg.repeat, 0)
            run.record(dataset=ds, tf=tf_name, method=spec, phase="build_cold", ms=ms, ms_runs=runs,
                       bytes=index.stats()["bytes"])
        if not store.done(dataset=ds, tf=tf_name, method=spec, phase="rebuild"):
            ms, runs, index = median_ms(lambda: build_index(vol, tf, method, **opts), cfg.repeat, cfg.warmup)
            run.record(dataset=ds, tf=tf_name, method=spec, phase="rebuild", ms=ms, ms_runs=runs,
                       bytes=index.stats()["bytes"], index_stats=index.stats(), exact=bool(index.exact))
        else:
            index = build_index(vol, tf, method, **opts)
        for w, h in cfg.sizes:
            for i, view in enumerate(run.views(tf_name)):
                name = view_name(view)
                if store.done(dataset=ds, tf=tf_name, method=spec, width=w, height=h, view=name, phase="render"):
                    continue
                say(f"{ds}/{tf_name}: {spec} {w}x{h} {name}")
                cam = self.camera(view)
                ms, runs, img = median_ms(lambda: render(vol, tf, cam, w, h, dt=self.dt, index=index),
                                          cfg.repeat, cfg.warmup)
                extra: dict[str, Any] = {}
                if method == "naive":
                    self._reference[(w, h, name)] = img.rgba[..., :3].astype(np.float16)
                if not index.exact:
                    extra["psnr_vs_naive"] = psnr(img.rgba, self.reference(w, h, view))
                if method == "naive" and i == 0 and cfg.images_dir is not None:
                    path = Path(cfg.images_dir) / image_name(ds, tf_name, f"{w}x{h}", name, "sparsecast")
                    extra["image"] = str(save_png(img.rgba, path))
                run.record(dataset=ds, tf=tf_name, method=spec, phase="render", view=name, ms=ms, ms_runs=runs,
                           samples=img.stats["samples"], samples_nonempty=img.stats["samples_nonempty"],
                           bytes=index.stats()["bytes"], width=w, height=h, dt=img.stats["dt"],
                           exact=bool(index.exact), **extra)

    def peer(self, peer: str, module: Any) -> None:
        run, cfg, ds, tf_name = self.runner, self.cfg, self.ds, self.tf_name
        run.progress.say(f"{ds}/{tf_name}: {peer} setup")
        try:
            scene = module.Scene(self.vol, self.tf, self.dt)
        except Exception as exc:  # a peer that cannot take this volume is a note, not a crash
            run.skip(peer, "peer", f"{ds}/{tf_name}: {type(exc).__name__}: {exc}")
            return
        for w, h in cfg.sizes:
            for i, view in enumerate(run.views(tf_name, peer=True)):
                name = view_name(view)
                if run.store.done(dataset=ds, tf=tf_name, method=peer, width=w, height=h, view=name, phase="render"):
                    continue
                run.progress.say(f"{ds}/{tf_name}: {peer} {w}x{h} {name}")
                cam = self.camera(view)
                for _ in range(max(cfg.warmup, 1)):  # the first frame also sets the peer up
                    scene.render(cam, w, h)
                cpu0, wall0 = time.process_time(), time.perf_counter()
                frames = [scene.render(cam, w, h) for _ in range(cfg.repeat)]
                # CPU time over wall time: how many cores the peer kept busy (all threads).
                cores = (time.process_time() - cpu0) / max(time.perf_counter() - wall0, 1e-9)
                timed = [ms for _, ms in frames]
                rgba = frames[-1][0]
                extra: dict[str, Any] = {"psnr_vs_naive": psnr(rgba, self.reference(w, h, view)),
                                         "cores_busy": round(cores, 2)}
                if i == 0 and cfg.images_dir is not None:
                    path = Path(cfg.images_dir) / image_name(ds, tf_name, f"{w}x{h}", name, peer)
                    extra["image"] = str(save_png(rgba, path))
                run.record(dataset=ds, tf=tf_name, method=peer, phase="render", view=name,
                           ms=float(np.median(timed)), ms_runs=timed, width=w, height=h, dt=self.dt,
                           peer=True, exact=False, **extra)


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


def add_ratios(records: Iterable[Record]) -> None:
    """Ratios between records of the same run, added in place to every render record
    outside the sections (which compute their own).

    ``speedup_vs_naive`` (naive ms / ms, same dataset, TF, size and view),
    ``msamples_per_s``, ``samples_vs_oracle`` (samples taken / samples in non-empty
    space: 1 is a perfect skipper) and, for peers, ``ratio_to_best`` (peer ms /
    ms of our fastest exact index on the same case: above 1 means we are faster).
    """
    recs = [r for r in records if r.get("phase") == "render" and not r.get("section")]

    def case(r: Record) -> tuple:
        return (r["dataset"], r["tf"], r["view"], r.get("width"), r.get("height"))

    naive = {case(r): r["ms"] for r in recs if r["method"] == "naive"}
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
        if r.get("peer"):
            b = best.get(case(r))
            r["ratio_to_best"] = r["ms"] / b if b else None
