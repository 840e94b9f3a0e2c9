"""Benchmark section ``bih``: the BIH paper's Tables 3-6 on our data, plus particles.

Per volume (the ``demo`` and ``mni152`` by default; unavailable ones skipped) and
resampling factor r in {1, 1.5, 2}:

- Table 3 (``phase="build_intermediate"``): elements (count, % of grid points),
  element extraction and intermediate BIH build ms, nodes, % single-child nodes,
  max depth, packed bytes;
- Table 4 (``phase="build_lod"``): LoD cut + packing ms, nodes, depth, bytes and the
  size relative to the 16-bit uniform grid (``grid_ratio``);
- Tables 5/6 (``phase="render"``): frame ms of ``naive``, ``bih`` ``ess`` and of the
  single- and multi-sample modes at this r, measured in the same run, with
  ``speedup`` over naive and the PSNR of the approximate images against naive.

Element sets estimated above :data:`MAX_ELEMENTS` are skipped (``phase="skipped"``:
the 2-core benchmark machine has 23 GB). Particles (``nbody-particles-*``): BIH
build ms, nodes, bytes and frame ms of :func:`render_particles`.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numpy as np

from ..camera import Camera
from ..datasets import nbody_particles
from ..index import build_index
from ..index.bih import ParticleBIH, build_bih
from ..elements import voxel_elements
from ..render import render
from ..render.particles import render_particles
from .catalog import DATASETS
from .images import psnr
from .timing import median_ms

__all__ = ["run", "DEFAULT_DATASETS", "RESAMPLING", "MAX_ELEMENTS", "PARTICLE_COUNTS"]

DEFAULT_DATASETS = ("demo", "mni152")
RESAMPLING = (1.0, 1.5, 2.0)
#: larger element sets are skipped (about 350 bytes per element while building)
MAX_ELEMENTS = 8_000_000
PARTICLE_COUNTS = (100_000, 1_000_000)
VIEW = (30.0, 20.0)


def _frame(render_once: Callable, repeat: int, warmup: int) -> tuple[float, float, object]:
    """Median marching ms (``stats["ms"]``) and median wall ms of repeated frames."""
    marching: list[float] = []

    def once():
        img = render_once()
        marching.append(img.stats["ms"])
        return img

    wall, _, img = median_ms(once, repeat, warmup)
    return statistics.median(marching[warmup:]), wall, img


def run(datasets: list[str] | None, *, width: int, height: int, repeat: int, warmup: int,
        record: Callable[..., None]) -> None:
    """Measure Tables 3-6 (see the module docstring) and the particle renderer."""
    names = list(DEFAULT_DATASETS) if datasets is None else list(datasets)
    for name in names:
        ds = DATASETS.get(name)
        if ds is None or not ds.available():
            record(dataset=name, method="bih", phase="skipped", reason="dataset not available")
            continue
        _volume_tables(name, ds.load(), ds.make_tf, width, height, repeat, warmup, record)
    if datasets is None:
        for n in PARTICLE_COUNTS:
            _particles(n, width, height, repeat, warmup, record)


def _volume_tables(name, vol, make_tf, width, height, repeat, warmup, record) -> None:
    tf = make_tf(vol)
    cam = Camera.orbit(vol, *VIEW)
    grid_bytes = 2 * int(np.prod(vol.shape))
    view = f"az{VIEW[0]:g}_el{VIEW[1]:g}"
    common = dict(dataset=name, width=width, height=height, view=view)

    naive_ms, naive_wall, ref = _frame(lambda: render(vol, tf, cam, width, height, index="naive"), repeat, warmup)
    record(method="naive", phase="render", ms=naive_ms, wall_ms=naive_wall, samples=ref.stats["samples"],
           **common)
    ref_rgba = ref.rgba

    ess_build, _, ess = median_ms(lambda: build_index(vol, tf, "bih", mode="ess"), repeat, warmup)
    record(dataset=name, method="bih:mode=ess", phase="rebuild", ms=ess_build, nodes=ess.tree.n_nodes,
           depth=ess.tree.max_depth, bytes=ess.nbytes, bricks=len(ess.elements))
    ess_ms, wall, img = _frame(lambda: render(vol, tf, cam, width, height, index=ess), repeat, warmup)
    record(method="bih:mode=ess", phase="render", ms=ess_ms, wall_ms=wall, samples=img.stats["samples"],
           speedup=naive_ms / ess_ms, max_abs_diff=float(np.abs(img.rgba - ref_rgba).max()), **common)

    base = None
    for r in RESAMPLING:
        tag = f"r={r:g}"
        if base is not None and base * r ** 3 > MAX_ELEMENTS:
            record(dataset=name, method=f"bih:{tag}", phase="skipped",
                   reason=f"about {int(base * r ** 3)} elements > {MAX_ELEMENTS}")
            continue
        t0 = time.perf_counter()
        el = voxel_elements(vol, 0.1, r)
        el_ms = (time.perf_counter() - t0) * 1e3
        base = len(el) / r ** 3 if base is None else base
        # Builds are the expensive part (seconds at 2 M elements): at most 3 runs.
        build_ms, runs, tree = median_ms(lambda: build_bih(el), min(repeat, 3), 0)
        st = tree.stats()
        record(dataset=name, method=f"bih:{tag}", phase="build_intermediate", ms=build_ms, ms_runs=runs,
               elements=len(el), elements_pct=100.0 * len(el) / el.info["grid_points"], elements_ms=el_ms,
               nodes=st["nodes"], single_child_pct=st["single_child_pct"], depth=st["max_depth"],
               bytes=st["bytes"], grid_bytes=grid_bytes)
        lod_ms, runs, packed_lod = median_ms(lambda: (lambda t: (t, t.pack()))(tree.lod()), repeat, warmup)
        lod, packed = packed_lod
        record(dataset=name, method=f"bih:{tag}", phase="build_lod", ms=lod_ms, ms_runs=runs,
               nodes=lod.n_nodes, depth=lod.max_depth, bytes=packed.nbytes,
               grid_ratio=packed.nbytes / grid_bytes)
        del tree, lod, packed_lod, packed
        for mode in ("single-sample", "multi-sample"):
            idx = build_index(vol, tf, "bih", mode=mode, resample=r)
            ms, wall, img = _frame(lambda: render(vol, tf, cam, width, height, index=idx), repeat, warmup)
            record(method=f"bih:mode={mode},{tag}", phase="render", ms=ms, wall_ms=wall,
                   samples=img.stats["samples"], speedup=naive_ms / ms, ess_over_mode=ess_ms / ms,
                   psnr=psnr(img.rgba, ref_rgba), nodes=idx.tree.n_nodes, bytes=idx.nbytes, **common)
        del el


def _particles(n, width, height, repeat, warmup, record) -> None:
    ps = nbody_particles(n)
    name = f"nbody-particles-{n // 1000}k"
    build_ms, runs, tree = median_ms(lambda: ParticleBIH.build(ps), min(repeat, 3), 0)
    st = tree.stats()
    record(dataset=name, method="bih-particles", phase="build_intermediate", ms=build_ms, ms_runs=runs,
           elements=n, nodes=st["nodes"], single_child_pct=st["single_child_pct"], depth=st["max_depth"],
           bytes=st["bytes"])
    cam = Camera.orbit(ps, *VIEW)
    for scale in (1.0, 2.0):
        # opacity 1: the paper's opaque-centred spheres, comparable with earlier runs
        ms, wall, img = _frame(lambda: render_particles(tree, cam, width, height, radius_scale=scale, opacity=1.0),
                               repeat, warmup)
        record(dataset=name, method=f"bih-particles:radius_scale={scale:g}", phase="render", ms=ms,
               wall_ms=wall, width=width, height=height, sphere_tests=img.stats["sphere_tests"],
               coverage=float(img.rgba[..., 3].mean()))
