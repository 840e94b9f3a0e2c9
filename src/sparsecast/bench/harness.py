"""The benchmark runner: datasets x TFs x methods x image sizes x views, then peers and sections.

One record per measurement (warm-up excluded, median of N). The frames of one
scene (dataset, TF, size, view) are timed in interleaved rounds, every method and
peer in turn (A B C A B C ...), so that all of them see the same machine; each
render record holds its raw runs, spread, CPU time and cores busy. Records go to a
:class:`~sparsecast.bench.progress.ResultStore` as they are taken, so a long run
can be interrupted and resumed: finished cases are skipped, not re-measured.
What a run measures is a :class:`~.config.BenchConfig`; which cases that makes is
the :class:`~.plan.CasePlan`; the ratios between records are :func:`~.ratios.add_ratios`.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..camera import Camera
from ..index import build_index, parse_index_spec
from ..render import render
from ..transfer import TransferFunction
from ..volume import Volume
from .bounds import cell_bound, volume_occupancy
from .catalog import DATASETS, dense_tf
from .config import BenchConfig, section_dataset_names
from .images import image_name, psnr, save_png
from .irt import irt_build_times
from .machine import machine_info
from .peers import PeerUnavailable, load_peer
from .plan import CasePlan, Key, build_key, classify_key, dataset_key, render_key
from .progress import Progress, ResultStore
from .ratios import add_ratios
from .suites import view_name
from .timing import Frame, interleaved, median_ms

__all__ = ["run_benchmarks", "finished_records"]

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
    approximate indices, the PSNR against the naive image; the peers render their
    views in the same interleaved rounds (PSNR against our naive image). Then the
    sections (``irt``,
    ``bih``, ``surface``...), and finally the ratios of :func:`~.ratios.add_ratios`.

    Parameters
    ----------
    config : BenchConfig
    progress : Progress or callable, optional
        Told about each case (a callable receives one message string per step).
    store : ResultStore, optional
        Where records go as they are taken; cases whose key it already holds are
        skipped (a resumed run). Default: in memory only.

    Returns
    -------
    list of dict
        Every record of the store (this run's and a resumed journal's), with ratios.
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
    """One pass over a config: what is available, the plan of case keys, then the measurements."""

    def __init__(self, config: BenchConfig, store: ResultStore,
                 progress: Progress | Callable[[str], None] | None) -> None:
        # Dataset names a section knows go to it (the CLI routes them too, to fail early);
        # a copy, so that the caller's config is not changed.
        self.cfg = dataclasses.replace(config, datasets=list(config.datasets),
                                       section_datasets=list(config.section_datasets))
        unknown = self.cfg.route_datasets()
        self.store = store
        self.machine = machine_info()
        if progress is None:
            progress = Progress(0)
        elif not isinstance(progress, Progress):
            progress = _CallbackProgress(progress)
        self.progress = progress
        self.methods = [(spec, *parse_index_spec(spec)) for spec in config.methods]
        self.peers = self._available_peers()
        sections = self._available_sections()
        for name in unknown:
            self.skip(name, "dataset", "unknown dataset: neither a volume of the catalogue nor a name a section knows")
        datasets = []
        for name in self.cfg.datasets:
            if DATASETS[name].available():
                datasets.append(name)
            else:
                self.skip(name, "dataset", "data not found (no shared data folder or file)")
        self.plan = CasePlan(
            datasets=datasets, tfs=["default"] + (["dense"] if config.dense_tf else []),
            methods=[spec for spec, _, _ in self.methods], peers=[name for name, _ in self.peers],
            sections=sections, sizes=list(config.sizes), views=list(config.views),
            dense_views=config.dense_views, peer_views=config.peer_views,
            section_data=self._section_data(sections),
        )
        keys = self.plan.keys()
        self.progress.total = len(keys)
        self.progress.done_count = sum(self.done(k) for k in keys)

    # -- bookkeeping ---------------------------------------------------------
    def done(self, key: Key) -> bool:
        return self.store.done(**key)

    def all_done(self, keys: list[Key]) -> bool:
        return all(self.done(k) for k in keys)

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

    def _section_data(self, sections: list[str]) -> dict[str, tuple[str, ...]]:
        """The ``--dataset`` names each section knows (``BenchConfig.route_datasets``)."""
        out = {}
        for name in sections:
            own = set(section_dataset_names(name)) if name != "irt" else set()
            names = tuple(n for n in self.cfg.section_datasets if n in own)
            if names:
                out[name] = names
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

    # -- the measurements ------------------------------------------------------
    def all(self) -> None:
        plan = self.plan
        if any(not self.all_done(plan.dataset_keys(ds)) for ds in plan.datasets):
            _warm_up_kernels([(name, opts) for _, name, opts in self.methods])
        for ds in plan.datasets:
            if self.all_done(plan.dataset_keys(ds)):
                continue
            self.dataset(ds)
        for name in plan.sections:
            if not self.done(self.plan.section_key(name)):
                self.section(name)

    def dataset(self, ds_name: str) -> None:
        cfg, say = self.cfg, self.progress.say
        ds = DATASETS[ds_name]
        say(f"{ds_name}: loading")
        t0 = time.perf_counter()
        vol = ds.load()
        key = dataset_key(ds_name, "load")
        if not self.done(key):
            self.record(**key, ms=(time.perf_counter() - t0) * 1e3, bytes=vol.nbytes,
                        dims=list(vol.dims), dtype=str(vol.dtype))
        # A dtype the first warm-up did not cover (uint16 CT, float64): its kernels compile
        # here, not in the first timed brick statistics or build of the paper suite (no warm-up runs).
        _warm_up_kernels([(name, opts) for _, name, opts in self.methods], (vol.dtype,))
        key = dataset_key(ds_name, "brick_stats")
        if not self.done(key):
            say(f"{ds_name}: brick statistics")
            fresh = iter([Volume(vol.data, vol.spacing, vol.origin) for _ in range(cfg.repeat)])
            ms, runs, stats = median_ms(lambda: next(fresh).brick_stats(8), cfg.repeat, 0)
            self.record(**key, ms=ms, ms_runs=runs, bytes=stats.nbytes)
        tfs = {"default": ds.make_tf(vol)}
        if cfg.dense_tf:
            tfs["dense"] = dense_tf(vol)
        for tf_name, tf in tfs.items():
            if not self.all_done(self.plan.tf_keys(ds_name, tf_name)):
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
                # The --dataset names this section knows, else its defaults.
                names = list(self.plan.section_data.get(name, ())) or None
                module.run(names, width=w, height=h, repeat=cfg.repeat, warmup=max(cfg.warmup, 1), record=record)
        except Exception as exc:  # one broken section must not end a long run
            last = traceback.extract_tb(exc.__traceback__)[-1]
            self.skip(name, "section", f"failed: {type(exc).__name__}: {exc} ({Path(last.filename).name}:{last.lineno})")
            return
        self.store.add_many(recs + [{**_BLANK, **self.plan.section_key(name), "machine": self.machine}])
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
        # (dt, cell occupancy of the TF) for the cell bound of the naive frames (bench.bounds)
        self._occupancy: tuple[float, np.ndarray] | None = None

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
        """Build every method, set every peer up, then time the frames of each (size,
        view) in interleaved rounds (:func:`~.timing.interleaved`)."""
        run, ds, tf_name = self.runner, self.ds, self.tf_name
        key = classify_key(ds, tf_name)
        if not run.done(key):
            bricks = self.vol.brick_stats(8)
            ms, runs, nonempty = median_ms(lambda: self.tf.classify(bricks.vmin, bricks.vmax), self.cfg.repeat, 1)
            run.record(**key, ms=ms, ms_runs=runs, occupancy=float(np.mean(nonempty)), bricks=int(nonempty.size))
        indices: dict[str, tuple[str, Any]] = {}
        for spec, method, opts in run.methods:
            if not run.all_done(run.plan.method_keys(ds, tf_name, spec)):
                indices[spec] = (method, self.build(spec, method, opts))
        scenes: dict[str, Any] = {}
        for peer, module in run.peers:
            if not run.all_done(run.plan.render_keys(ds, tf_name, peer, peer=True)):
                scene = self.peer_scene(peer, module)
                if scene is not None:
                    scenes[peer] = scene
        peer_views = run.plan.views_for(tf_name, peer=True)
        for w, h in self.cfg.sizes:
            for i, view in enumerate(run.plan.views_for(tf_name)):
                self.frames(w, h, i, view, indices, scenes if view in peer_views else {})
        for scene in scenes.values():  # e.g. pyvista's OpenGL context
            close = getattr(scene, "close", None)
            if close is not None:
                close()

    def build(self, spec: str, method: str, opts: dict[str, Any]) -> Any:
        """Time ``build_cold`` and ``rebuild`` (unless journaled) and return the index."""
        run, cfg, ds, tf_name, vol, tf = self.runner, self.cfg, self.ds, self.tf_name, self.vol, self.tf
        run.progress.say(f"{ds}/{tf_name}: {spec} build")
        key = build_key(ds, tf_name, spec, "build_cold")
        if not run.done(key):
            # A fresh Volume object per run: no cached brick statistics.
            fresh = iter([Volume(vol.data, vol.spacing, vol.origin) for _ in range(cfg.repeat)])
            ms, runs, index = median_ms(lambda: build_index(next(fresh), tf, method, **opts), cfg.repeat, 0)
            run.record(**key, ms=ms, ms_runs=runs, bytes=index.stats()["bytes"])
        key = build_key(ds, tf_name, spec, "rebuild")
        if not run.done(key):
            ms, runs, index = median_ms(lambda: build_index(vol, tf, method, **opts), cfg.repeat, cfg.warmup)
            run.record(**key, ms=ms, ms_runs=runs, bytes=index.stats()["bytes"], index_stats=index.stats(),
                       exact=bool(index.exact))
            return index
        return build_index(vol, tf, method, **opts)

    def peer_scene(self, peer: str, module: Any) -> Any:
        """The peer's scene of this volume and TF, or None (noted) when it cannot take it."""
        run = self.runner
        run.progress.say(f"{self.ds}/{self.tf_name}: {peer} setup")
        try:
            return module.Scene(self.vol, self.tf, self.dt)
        except Exception as exc:  # a peer that cannot take this volume is a note, not a crash
            run.skip(peer, "peer", f"{self.ds}/{self.tf_name}: {type(exc).__name__}: {exc}")
            return None

    def frames(self, w: int, h: int, i: int, view: tuple[float, float],
               indices: dict[str, tuple[str, Any]], scenes: dict[str, Any]) -> None:
        """One scene (size, view): every method and peer not yet journaled takes turns,
        a warm-up round first (compiles, peer set-up), then ``repeat`` timed rounds."""
        run, cfg, ds, tf_name, vol, tf = self.runner, self.cfg, self.ds, self.tf_name, self.vol, self.tf
        cam = self.camera(view)
        keys = {name: render_key(ds, tf_name, name, (w, h), view) for name in [*indices, *scenes]}
        todo = {name: k for name, k in keys.items() if not run.done(k)}
        if not todo:
            return
        name = view_name(view)
        run.progress.say(f"{ds}/{tf_name}: {w}x{h} {name}: {', '.join(todo)} interleaved")
        frames: dict[str, Frame] = {}
        for spec in todo:
            if spec in indices:
                index = indices[spec][1]
                # Ours: the wall time of render() (image allocation included).
                frames[spec] = lambda index=index: (render(vol, tf, cam, w, h, dt=self.dt, index=index), None)
            else:
                # Peers: their own frame time (the render call, pixel read-back excluded
                # unless the peer says otherwise); CPU and cores busy around the whole call.
                frames[spec] = lambda scene=scenes[spec]: scene.render(cam, w, h)
        timed = interleaved(frames, cfg.repeat, max(cfg.warmup, 1))
        if "naive" in timed:
            self._reference[(w, h, name)] = timed["naive"].result.rgba[..., :3].astype(np.float16)
        for spec, runs in timed.items():
            extra: dict[str, Any] = {}
            if spec in indices:
                method, index = indices[spec]
                img = runs.result
                if not index.exact:
                    extra["psnr_vs_naive"] = psnr(img.rgba, self.reference(w, h, view))
                if method == "naive":
                    # Untimed: the samples a perfect cell-exact skipper takes (bench.bounds).
                    dt = img.stats["dt"]
                    if self._occupancy is None or self._occupancy[0] != dt:  # one per case, every view
                        self._occupancy = (dt, volume_occupancy(vol, tf, dt))
                    bound = cell_bound(vol, tf, cam, w, h, dt, img.stats["ert"], occupancy=self._occupancy[1])
                    if bound is not None:
                        extra["samples_cell_bound"] = bound["samples_cell_bound"]
                if method == "naive" and i == 0 and cfg.images_dir is not None:
                    path = Path(cfg.images_dir) / image_name(ds, tf_name, f"{w}x{h}", name, "sparsecast")
                    extra["image"] = str(save_png(img.rgba, path))
                run.record(**todo[spec], **runs.fields(), interleaved_with=list(timed),
                           samples=img.stats["samples"], samples_nonempty=img.stats["samples_nonempty"],
                           bytes=index.stats()["bytes"], dt=img.stats["dt"], exact=bool(index.exact), **extra)
            else:
                scene = scenes[spec]
                rgba = runs.result
                extra["psnr_vs_naive"] = psnr(rgba, self.reference(w, h, view))
                samples = getattr(scene, "samples", None)
                if samples is not None:  # a peer that knows (or estimates) its sample count
                    extra["samples"] = samples(cam, w, h)
                extra.update(getattr(scene, "info", {}))  # e.g. which OpenGL renderer ran
                if i == 0 and cfg.images_dir is not None:
                    path = Path(cfg.images_dir) / image_name(ds, tf_name, f"{w}x{h}", name, spec)
                    extra["image"] = str(save_png(rgba, path))
                run.record(**todo[spec], **runs.fields(), interleaved_with=list(timed), dt=self.dt,
                           peer=True, exact=False, **extra)


_WARM: set[tuple[str, str]] = set()


def _warm_up_kernels(methods: list[tuple[str, dict[str, Any]]], dtypes=(np.float32, np.uint8)) -> None:
    """Compile (or load from cache) every kernel on a tiny volume of each dtype, outside
    all timings (once per dtype and method in a process: each is a specialisation of its own)."""
    from ..datasets import nbody_blobs

    for dtype in dtypes:
        todo = [(name, opts) for name, opts in methods if (np.dtype(dtype).str, f"{name}{opts}") not in _WARM]
        if not todo and (np.dtype(dtype).str, "") in _WARM:
            continue
        small = nbody_blobs(16, n_clusters=2, blobs_per_cluster=4, dtype=dtype)
        tf = TransferFunction.preset("viridis", small.value_range)
        cam = Camera.orbit(small)
        small.brick_stats(8)
        tf.classify(small.brick_stats(8).vmin, small.brick_stats(8).vmax)
        _WARM.add((np.dtype(dtype).str, ""))
        for name, opts in todo:
            render(small, tf, cam, 8, 8, index=name, **opts)
            _WARM.add((np.dtype(dtype).str, f"{name}{opts}"))
