"""Compile every kernel ahead of use: ``sparsecast compile`` and :func:`compile_kernels`.

Numba compiles a kernel the first time a process calls it with new argument types,
and the DVR driver specialises per index record type *and* voxel dtype: a cold start
of one index on one dtype takes tens of seconds, the surface builds as long again.
The kernels are cached on disk (:mod:`sparsecast.kernel_cache`), so compiling them
once, here, makes every later process start from the cache.

The plan (:func:`plan`) is a list of steps, one per kernel group, each of which runs
the real code path on a tiny input: per dtype, the brick statistics and, per index,
a build and an unshaded and a shaded 16x16 frame (the driver specialisation for that
record type and dtype); for the indices ``index="auto"`` picks from, the iso modes,
bricked storage and label TFs (each its own specialisation); the exact BVH and the
RBVH builds over a small mesh and a point cloud, their camera and free-ray kernels;
the particle BIH and its renderer.
A step that finds its kernels in the cache takes milliseconds.
"""

from __future__ import annotations

import multiprocessing
import queue
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import kernel_cache
from ._util.checks import as_int, fail, one_of
from .camera import Camera
from .errors import ParameterError, SparsecastError
from .index import available_indices, build_index, parse_index_spec
from .index.auto import EDITING_INDEX, SPARSE_INDEX
from .index.warm import tiny_volume
from .render import render
from .transfer import TransferFunction
from .volume import SUPPORTED_DTYPES

__all__ = ["compile_kernels", "plan", "CompileStep", "CompileReport", "GROUPS", "DEFAULT_DTYPES",
           "APPROXIMATE_MODES", "AUTO_INDICES", "LABEL_INDICES"]

#: the kernel groups, in plan order (``sparsecast compile --only``)
GROUPS = ("volume", "surface", "particles")

#: dtypes compiled by default: the common ones (8- and 16-bit scans, float fields);
#: int16 and float64 cost a full driver specialisation each and are asked for by name
DEFAULT_DTYPES = ("uint8", "uint16", "float32")

#: BIH build options beyond the default mode: each approximate mode has its own
#: record type and integrator, hence its own driver specialisation
APPROXIMATE_MODES = ("bih:mode=single-sample", "bih:mode=multi-sample")

#: the indices ``index="auto"`` picks from (naive, the sparse and the editing index):
#: label volumes (nearest and smooth sampling, for the integer dtypes), the iso modes and
#: bricked storage (each a driver specialisation of its own) are compiled for these by
#: default; ``indices=`` names others
AUTO_INDICES = ("naive", SPARSE_INDEX, EDITING_INDEX)
LABEL_INDICES = AUTO_INDICES

#: pixels per side of a warm-up frame
FRAME = 16


@dataclass(frozen=True)
class CompileStep:
    """One kernel group to compile: ``run()`` exercises it on a tiny input.

    Attributes
    ----------
    group : str
        One of :data:`GROUPS`.
    label : str
        What it compiles, e.g. ``"volume uint8 kdtree-deep: build, frame"``.
    run : callable
        Takes no argument; returns nothing.
    lane : str
        Steps of one lane share kernels (a dtype's volume steps share its marcher and
        samplers) and run in one process, in plan order (:func:`compile_kernels` with
        ``jobs > 1``); empty: the group is the lane.
    """

    group: str
    label: str
    run: Callable[[], None] = field(repr=False)
    lane: str = ""


@dataclass
class CompileReport:
    """What :func:`compile_kernels` did.

    Attributes
    ----------
    steps : list of (label, ms, compile_ms)
        Per step: wall time (compilation, cache loads and the tiny run), and the
        part of it Numba spent compiling (0 when everything came from the cache).
    total_ms, compile_ms : float
        Sums over the steps (with several processes, more than the wall time).
    cache_dir : Path or None
        The kernel cache folder (None: Numba's default beside the sources).
    wall_ms : float
        Wall time of the whole run.
    jobs : int
        Processes that compiled (1: this one).
    """

    steps: list[tuple[str, float, float]]
    total_ms: float
    compile_ms: float
    cache_dir: Path | None
    wall_ms: float = 0.0
    jobs: int = 1


def _dtypes(dtypes: str | Sequence[str] | None, name: str) -> list[np.dtype]:
    names = [str(np.dtype(d)) for d in SUPPORTED_DTYPES]
    if dtypes is None:
        return [np.dtype(d) for d in DEFAULT_DTYPES]
    if isinstance(dtypes, str):
        dtypes = [dtypes]
    if list(dtypes) == ["all"]:
        return list(SUPPORTED_DTYPES)
    out: list[np.dtype] = []
    for d in dtypes:
        one_of(str(d), name, names, expected=f"'all' or some of {', '.join(names)}")
        if np.dtype(d) not in out:
            out.append(np.dtype(d))
    return out


def _index_specs(indices: Sequence[str] | None, name: str) -> list[str]:
    if indices is None:
        # The package's own indices (a test's or a user's registered one renders through
        # the uncached driver copy: nothing to keep), then the BIH's approximate modes.
        from .index.registry import index_class

        own = [n for n in available_indices() if index_class(n).__module__.startswith("sparsecast.")]
        return own + list(APPROXIMATE_MODES)
    if isinstance(indices, str):
        indices = [indices]
    specs = []
    for spec in indices:
        try:
            index, _ = parse_index_spec(spec)
        except ParameterError as exc:  # an unknown index or option, named
            raise ParameterError(f"{name}: {exc}") from None
        if index == "auto":
            raise fail(name, "index names (auto picks one of them at render time)", spec)
        specs.append(spec)
    return specs


def plan(
    dtypes: str | Sequence[str] | None = None,
    indices: Sequence[str] | None = None,
    groups: Sequence[str] | None = None,
    *,
    names: tuple[str, str, str] = ("dtypes", "indices", "groups"),
) -> list[CompileStep]:
    """The steps :func:`compile_kernels` runs, in order (nothing is compiled here).

    Parameters
    ----------
    dtypes : sequence of str, or "all", optional
        Voxel dtypes of the volume steps (default :data:`DEFAULT_DTYPES`).
    indices : sequence of str, optional
        Index specs ``NAME[:KEY=VALUE,...]`` of the volume steps (default: every
        index of the package, and the BIH's approximate modes).
    groups : sequence of str, optional
        Some of :data:`GROUPS` (default all).
    names : (str, str, str)
        What error messages call the three (the CLI: ``--dtype``, ``--index``, ``--only``).

    Returns
    -------
    list of CompileStep
        Volume steps: per dtype, the brick statistics, then one per index spec, then
        per exact index of :data:`AUTO_INDICES` (or of ``indices``) the iso modes, bricked
        storage and, for integer dtypes, label TFs; then the surface steps, then the
        particles step.

    Raises
    ------
    ParameterError
        An unknown dtype, index, index option or group.
    """
    chosen = list(GROUPS) if groups is None else [
        one_of(g, names[2], GROUPS, expected="some of " + ", ".join(GROUPS)) for g in groups]
    steps: list[CompileStep] = []
    if "volume" in chosen:
        specs = _index_specs(indices, names[1])
        # Exact indices only: the BIH's approximate modes have no iso or label path.
        mode_specs = [s for s in (specs if indices is not None else AUTO_INDICES)
                      if s in specs and parse_index_spec(s)[1].get("mode", "ess") == "ess"]
        for dtype in _dtypes(dtypes, names[0]):
            lane = f"volume {dtype}"
            steps.append(CompileStep("volume", f"volume {dtype}: brick statistics",
                                     _bind(_brick_stats, dtype), lane))
            steps.extend(CompileStep("volume", f"volume {dtype} {spec}: build, frame", _bind(_volume, dtype, spec),
                                     lane) for spec in specs)
            steps.extend(CompileStep("volume", f"volume {dtype} iso {spec}: iso, iso+dvr frames",
                                     _bind(_iso, dtype, spec), lane) for spec in mode_specs)
            steps.extend(CompileStep("volume", f"volume {dtype} bricked {spec}: frame",
                                     _bind(_bricked, dtype, spec), lane) for spec in mode_specs)
            if dtype.kind in "iu":  # label volumes: integer ids, nearest and smooth sampling
                steps.extend(CompileStep("volume", f"volume {dtype} labels {spec}: build, frames",
                                         _bind(_labels, dtype, spec), lane) for spec in mode_specs)
    if "surface" in chosen:
        steps += [
            CompileStep("surface", "surface BVH: build", _bvh_build),
            CompileStep("surface", "surface RBVH: build (mesh)", _rbvh_build),
            CompileStep("surface", "surface RBVH: build (points)", _rbvh_points),
            CompileStep("surface", "surface RBVH: mip levels", _rbvh_mips),
            CompileStep("surface", "surface ray casting: camera and free rays", _surface_rays),
        ]
    if "particles" in chosen:
        steps.append(CompileStep("particles", "particles: BIH build, frame", _particles))
    return steps


def compile_kernels(
    dtypes: str | Sequence[str] | None = None,
    indices: Sequence[str] | None = None,
    groups: Sequence[str] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    *,
    names: tuple[str, str, str] = ("dtypes", "indices", "groups"),
    jobs: int = 1,
) -> CompileReport:
    """Compile (or load from the on-disk cache) every kernel of the chosen groups.

    Parameters
    ----------
    dtypes, indices, groups, names
        See :func:`plan`.
    progress : callable(done, total, label), optional
        Called as each step starts (``done`` steps finished, ``label`` the step
        starting) and once more with ``done == total`` and ``label == ""``.
    jobs : int, default 1
        Processes compiling at once. Numba compiles one function at a time per
        process (a global lock), so a machine's cores compile in parallel only in
        processes of their own: with ``jobs > 1`` the plan's lanes (a dtype's volume
        steps, the surface steps, particles; see :class:`CompileStep`) run in that many
        spawned processes, each lane's steps in order in one of them, all writing the
        same kernel cache. 1 runs every step here. An index registered outside the
        package (``indices`` naming one) runs here too: a fresh process does not know it.

    Returns
    -------
    CompileReport
        Per-step times (in plan order), their sums, the wall time and the cache folder.

    Raises
    ------
    ParameterError
        A bad dtype, index, group or ``jobs``.

    Examples
    --------
    >>> import sparsecast as sc
    >>> report = sc.compile_kernels(dtypes=["uint8"], indices=["naive"], groups=["volume"])  # doctest: +SKIP
    >>> report.cache_dir                                                                      # doctest: +SKIP
    PosixPath('/home/me/.cache/sparsecast/kernels-...')
    """
    jobs = as_int(jobs, "jobs", lo=1)
    steps = plan(dtypes, indices, groups, names=names)
    lanes = _lanes(steps)
    t0 = time.perf_counter()
    if jobs == 1 or len(lanes) < 2 or not _spawnable(indices):
        done = [_run_step(step, i, len(steps), progress) for i, step in enumerate(steps)]
        jobs = 1
    else:
        jobs = min(jobs, len(lanes))
        done = _run_lanes((dtypes, indices, groups, names), steps, lanes, jobs, progress)
    if progress is not None:
        progress(len(steps), len(steps), "")
    return CompileReport(done, sum(s[1] for s in done), sum(s[2] for s in done), kernel_cache.cache_dir(),
                         (time.perf_counter() - t0) * 1e3, jobs)


def _run_step(step: CompileStep, i: int, total: int,
              progress: Callable[[int, int, str], None] | None) -> tuple[str, float, float]:
    if progress is not None:
        progress(i, total, step.label)
    c0 = kernel_cache.compile_seconds()
    t0 = time.perf_counter()
    step.run()
    return step.label, (time.perf_counter() - t0) * 1e3, (kernel_cache.compile_seconds() - c0) * 1e3


def _lanes(steps: Sequence[CompileStep]) -> list[list[int]]:
    """Step numbers by lane, each lane in plan order, the lanes in order of first step
    (the volume dtypes, the longest, first: the pool ends on the short ones)."""
    lanes: dict[str, list[int]] = {}
    for i, step in enumerate(steps):
        lanes.setdefault(step.lane or step.group, []).append(i)
    return list(lanes.values())


def _spawnable(indices: Sequence[str] | str | None) -> bool:
    """Whether a fresh process knows every index named (the package's own)."""
    from .index.registry import index_class

    if indices is None:
        return True
    specs = [indices] if isinstance(indices, str) else list(indices)
    return all(index_class(parse_index_spec(s)[0]).__module__.startswith("sparsecast.") for s in specs)


def _run_lanes(args: tuple, steps: Sequence[CompileStep], lanes: list[list[int]], jobs: int,
               progress: Callable[[int, int, str], None] | None) -> list[tuple[str, float, float]]:
    """Run ``lanes`` in ``jobs`` spawned processes (see :func:`compile_kernels`); per-step
    results in plan order. Progress comes back over a queue as steps start and end."""
    ctx = multiprocessing.get_context("spawn")  # not fork: the parent may hold Numba's threads
    events = ctx.Queue()
    results: dict[int, tuple[str, float, float]] = {}
    finished = 0

    def report(kind: str, i: int) -> None:
        nonlocal finished
        if kind == "done":
            finished += 1
        elif progress is not None:
            progress(finished, len(steps), steps[i].label)

    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_init_lane_worker,
                               initargs=(events,))
    try:
        futures = [pool.submit(_run_lane, args, lane) for lane in lanes]
        pending = set(futures)
        while pending:
            _, pending = wait(pending, timeout=0.2)
            for f in futures:
                if f.done() and f.exception() is not None:
                    raise f.exception()
            while True:
                try:
                    report(*events.get_nowait())
                except queue.Empty:
                    break
        for f in futures:
            results.update(f.result())
        # A lane's last events can reach the queue after its result reached the pool (the
        # queue's feeder thread sends them): wait for them, so every step is reported.
        while finished < len(steps):
            report(*events.get(timeout=30))
    except BrokenProcessPool as exc:
        pool.shutdown(wait=False, cancel_futures=True)
        # Killed from outside, most likely for memory (each process holds its own Numba
        # and LLVM): the finished steps' kernels are in the cache, a rerun picks up there.
        raise SparsecastError(
            f"jobs: a compile process died before its steps were done ({exc}); out of memory? "
            f"Run again with fewer jobs (--jobs): kernels compiled so far are cached") from None
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    return [results[i] for i in range(len(steps))]


_events = None  # the lane workers' progress queue (set by _init_lane_worker)


def _init_lane_worker(events) -> None:
    global _events
    _events = events


def _run_lane(args: tuple, numbers: list[int]) -> dict[int, tuple[str, float, float]]:
    """In a worker: plan again (the same arguments give the same steps) and run ``numbers``."""
    dtypes, indices, groups, names = args
    steps = plan(dtypes, indices, groups, names=names)
    out = {}
    for i in numbers:
        _events.put(("start", i))
        out[i] = _run_step(steps[i], i, len(steps), None)
        _events.put(("done", i))
    return out


def _bind(fn: Callable, *args) -> Callable[[], None]:
    return lambda: fn(*args)


# -- the steps -------------------------------------------------------------------
def _tiny(dtype: np.dtype):
    """A tiny volume of ``dtype`` spanning the dtype's natural range, its TF and a camera."""
    hi = 1.0 if dtype.kind == "f" else float(min(np.iinfo(dtype).max, 4095))
    vol = tiny_volume(dtype, (0.0, hi))
    tf = TransferFunction.preset("viridis", value_range=vol.value_range)
    return vol, tf, Camera.orbit(vol, 30, 20)


def _brick_stats(dtype: np.dtype) -> None:
    vol, tf, _ = _tiny(dtype)
    b = vol.brick_stats(8)
    tf.classify(b.vmin, b.vmax)


def _volume(dtype: np.dtype, spec: str) -> None:
    vol, tf, cam = _tiny(dtype)
    name, options = parse_index_spec(spec)
    idx = build_index(vol, tf, name, **options)
    render(vol, tf, cam, FRAME, FRAME, index=idx)
    render(vol, tf, cam, FRAME, FRAME, index=idx, shading=True)  # the renderer's shaded path


def _iso(dtype: np.dtype, spec: str) -> None:
    vol, tf, cam = _tiny(dtype)
    name, options = parse_index_spec(spec)
    lo, hi = vol.value_range
    for mode in ("iso", "iso+dvr"):  # each mode marker is a driver specialisation
        render(vol, tf, cam, FRAME, FRAME, index=name, mode=mode, iso=0.5 * (lo + hi), **options)


def _bricked(dtype: np.dtype, spec: str) -> None:
    from .storage import BrickedVolume

    vol, tf, cam = _tiny(dtype)
    bricked = BrickedVolume(vol.data, spacing=vol.spacing, origin=vol.origin)
    name, options = parse_index_spec(spec)
    render(bricked, tf, cam, FRAME, FRAME, index=build_index(bricked, tf, name, **options))


def _labels(dtype: np.dtype, spec: str) -> None:
    vol = tiny_volume(dtype, (0.0, 2.0), labels=(1, 2))
    name, options = parse_index_spec(spec)
    for smooth in (False, True):  # nearest and smooth-label samplers
        tf = TransferFunction.labels([1, 2], smooth=smooth)
        render(vol, tf, Camera.orbit(vol, 30, 20), FRAME, FRAME, index=build_index(vol, tf, name, **options))


def _bvh_build() -> None:
    from .surface import build_bvh
    from .surface.mesh import warmup_mesh

    build_bvh(warmup_mesh())
    build_bvh(warmup_mesh(), splits=1.0)  # the spatial splits' kernels


def _rbvh_build() -> None:
    from .surface import build_rbvh
    from .surface.mesh import warmup_mesh

    build_rbvh(warmup_mesh())


def _rbvh_points() -> None:
    from .surface import build_rbvh
    from .surface.mesh import tiny_points

    build_rbvh(tiny_points())


def _rbvh_mips() -> None:
    from .surface import build_rbvh
    from .surface.mesh import warmup_mesh

    build_rbvh(warmup_mesh(), mip_levels=2)


def _surface_rays() -> None:
    from .surface import build_bvh, build_rbvh, raycast, render_surface
    from .surface.mesh import warmup_mesh

    mesh = warmup_mesh()
    cam = Camera.orbit(mesh, 30, 20)
    origins = np.array([[0.0, 0.0, 5.0]])
    directions = np.array([[0.0, 0.0, -1.0]])
    for idx in (build_bvh(mesh), build_rbvh(mesh)):
        render_surface(idx, cam, FRAME, FRAME)
        raycast(idx, origins, directions, footprint=(0.001, 0.001))


def _particles() -> None:
    from .datasets import nbody_particles
    from .render.particles import render_particles

    ps = nbody_particles(2000)
    render_particles(ps, Camera.orbit(ps, 30, 20), FRAME, FRAME)
