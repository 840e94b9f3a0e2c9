"""Benchmark section ``scale``: volumes larger than memory (issue 17).

A generated n-body-like float32 field (:func:`nbody_slabs`: a few thousand Gaussian
halos strung along filaments, about 3 % of the 8^3 bricks non-empty at 1024^3) is
written slab by slab (the generator never holds the whole array) to Zarr v3 (zstd
chunks of 64^3), and to ``.npy`` and raw copies (float32, and quantised to uint8: the
``-u8`` kinds) where the disk has room for them (:func:`_fits_on_disk`). Every (size,
source kind) case runs in a **fresh subprocess** (``python -m sparsecast.bench.scale``),
so that its peak RSS (``VmHWM``, see :func:`_peak_rss`) is that case's alone. The child
first runs the whole case on a 24^3 file of the same kind, so every kernel is
compiled (or loaded from the cache) before anything is timed, then measures:

- ``open_ms``: ``load_volume`` (Zarr: a lazy :class:`~sparsecast.storage.BrickedVolume`,
  whose chunk-parallel statistics pass is part of opening; ``.npy`` / raw: the default,
  a dense memory map when the data fits the memory budget, lazy otherwise);
- ``stats_ms`` and ``stats_gvox_s``: the brick statistics pass (``brick_stats(8)``);
- ``first_image_ms``: from ``load_volume`` to the first ``render(index="auto")`` image;
- per exact index: ``build_ms`` (first build), ``rebuild_ms`` (after a TF change), and
  the frame (median of ``repeat`` frames after ``warmup``);
- ``peak_rss``, ``rss_over_dense`` (peak RSS / dense bytes), ``resident_bricks``,
  ``stored_bricks`` and ``pool_bytes`` (a dense volume: all bricks, its array).

``naive`` marches every sample of the box: it runs up to :data:`NAIVE_MAX`^3 and is
recorded as skipped above (``reason`` says so). Sizes: :data:`SIZES`; 2048^3 (32 GB
dense) only when asked (``sizes=`` or ``SPARSECAST_BENCH_SCALE_MAX=2048``). The files
go to ``SPARSECAST_BENCH_SCALE_DIR`` (default a temporary folder) and are removed after.

Records: ``phase="load"`` (one per size and kind) and ``phase="render"`` /
``"skipped"`` (one per index), with ``dataset="nbody-<n>"``, ``size`` and ``kind``.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

__all__ = ["run", "nbody_slabs", "write_field", "SIZES", "KINDS", "NAIVE_MAX"]

#: edges of the default run; 2048 joins with SPARSECAST_BENCH_SCALE_MAX=2048
SIZES = (256, 512, 1024)
#: source kinds, in the order they run (``-u8``: the field quantised to uint8, the
#: 1 GiB-at-1024^3 case of the time-to-first-image target)
KINDS = ("zarr", "npy", "raw", "npy-u8", "raw-u8")
#: uint8 copies store ``round(field * U8_SCALE)`` clipped to 255 (halo cores saturate)
U8_SCALE = 48.0
#: largest edge naive renders at (it takes every sample: minutes per frame above)
NAIVE_MAX = 512
#: halos of the field, and the filaments they are strung along (unit-cube positions)
HALOS = 3000
FILAMENTS = 60
#: edge of the file the child renders first, compiling every kernel
WARM_EDGE = 24
CHUNK = 64


def _halos(seed: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(centres (h, 3) in [0, 1]^3 as (x, y, z), sigma (h,) as a fraction of the edge,
    amplitude (h,))``: halos on random segments between filament nodes, with jitter."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.08, 0.92, (FILAMENTS, 3))
    b = np.clip(a + rng.normal(0, 0.25, (FILAMENTS, 3)), 0.05, 0.95)
    f = rng.integers(0, FILAMENTS, HALOS)
    t = rng.random(HALOS)[:, None]
    centres = np.clip(a[f] + t * (b[f] - a[f]) + rng.normal(0, 0.01, (HALOS, 3)), 0.02, 0.98)
    sigma = np.exp(rng.normal(np.log(0.0028), 0.35, HALOS))
    amp = rng.pareto(1.5, HALOS) + 1.0
    return centres, sigma, amp.astype(np.float32)


def nbody_slabs(n: int, slab: int = CHUNK, seed: int = 4) -> Iterator[tuple[int, np.ndarray]]:
    """The n-body-like field of edge ``n`` as ``(z0, float32 slab (nz, n, n))`` pieces.

    Each halo adds ``amp * exp(-r^2 / (2 sigma^2))`` inside ``r < 3 sigma`` (sigma at least
    0.7 voxel) and nothing outside, so the background is exactly 0; halo parameters are
    fractions of the edge, so every size holds the same structure. Only one slab (and
    one halo's box) is in memory at a time.
    """
    centres, sigma, amp = _halos(seed)
    c = centres * (n - 1)
    s = np.maximum(sigma * n, 0.7)
    r = 3.0 * s
    for z0 in range(0, n, slab):
        z1 = min(z0 + slab, n)
        out = np.zeros((z1 - z0, n, n), np.float32)
        for h in np.flatnonzero((c[:, 2] + r > z0) & (c[:, 2] - r < z1 - 1)):
            lo = np.maximum(np.ceil(c[h] - r[h]), 0).astype(int)
            hi = np.minimum(np.floor(c[h] + r[h]), n - 1).astype(int)
            zlo, zhi = max(lo[2], z0), min(hi[2], z1 - 1)
            x = np.arange(lo[0], hi[0] + 1) - c[h, 0]
            y = np.arange(lo[1], hi[1] + 1) - c[h, 1]
            z = np.arange(zlo, zhi + 1) - c[h, 2]
            d2 = z[:, None, None] ** 2 + y[None, :, None] ** 2 + x[None, None, :] ** 2
            g = np.where(d2 < r[h] ** 2, amp[h] * np.exp(-d2 / (2 * s[h] ** 2)), 0.0).astype(np.float32)
            out[zlo - z0:zhi - z0 + 1, lo[1]:hi[1] + 1, lo[0]:hi[0] + 1] += g
        yield z0, out


def _fits_on_disk(folder: Path, nbytes: int) -> bool:
    """A dense copy is written when two of them (npy and raw) take at most a third of the free space."""
    return 2 * nbytes <= shutil.disk_usage(folder).free // 3


def write_field(n: int, folder: Path, kinds=KINDS, chunk: int = CHUNK) -> dict[str, Path]:
    """Write the field of edge ``n`` as each of ``kinds`` that fits, slab by slab (Zarr chunks of
    ``chunk``^3, every chunk written: lazy sources refuse a store with absent chunks); ``{kind: path}``."""
    import zarr

    folder.mkdir(parents=True, exist_ok=True)
    dense = n ** 3 * 4
    kinds = [k for k in kinds if k == "zarr" or _fits_on_disk(folder, dense // 4 if k.endswith("-u8") else dense)]
    paths: dict[str, Path] = {}
    z = npy = raw = npy8 = raw8 = None
    if "zarr" in kinds:
        paths["zarr"] = folder / f"nbody-{n}.zarr"
        z = zarr.create_array(str(paths["zarr"]), shape=(n, n, n), chunks=(chunk,) * 3, dtype="float32",
                              compressors=zarr.codecs.ZstdCodec(level=3), fill_value=0.0, overwrite=True,
                              config={"write_empty_chunks": True})
    if "npy" in kinds:
        paths["npy"] = folder / f"nbody-{n}.npy"
        npy = np.lib.format.open_memmap(paths["npy"], mode="w+", dtype=np.float32, shape=(n, n, n))
    if "raw" in kinds:
        paths["raw"] = folder / f"nbody-{n}_{n}x{n}x{n}_float32.raw"
        raw = open(paths["raw"], "wb")
    if "npy-u8" in kinds:
        paths["npy-u8"] = folder / f"nbody-{n}-u8.npy"
        npy8 = np.lib.format.open_memmap(paths["npy-u8"], mode="w+", dtype=np.uint8, shape=(n, n, n))
    if "raw-u8" in kinds:
        paths["raw-u8"] = folder / f"nbody-{n}-u8_{n}x{n}x{n}_uint8.raw"
        raw8 = open(paths["raw-u8"], "wb")
    try:
        for z0, slab in nbody_slabs(n, slab=chunk):
            if z is not None:
                z[z0:z0 + len(slab)] = slab
            if npy is not None:
                npy[z0:z0 + len(slab)] = slab
            if raw is not None:
                raw.write(slab.astype("<f4", copy=False).tobytes())
            if npy8 is not None or raw8 is not None:
                q = np.minimum(np.rint(slab * U8_SCALE), 255).astype(np.uint8)
                if npy8 is not None:
                    npy8[z0:z0 + len(slab)] = q
                if raw8 is not None:
                    raw8.write(q.tobytes())
    finally:
        for m in (npy, npy8):
            if m is not None:
                m.flush()
        del npy, npy8
        for f in (raw, raw8):
            if f is not None:
                f.close()
    return paths


def _scale_sizes() -> tuple[int, ...]:
    top = int(os.environ.get("SPARSECAST_BENCH_SCALE_MAX", max(SIZES)))
    return tuple(n for n in (*SIZES, 2048) if n <= top)


def run(datasets: list[str] | None, *, width: int, height: int, repeat: int, warmup: int,
        record: Callable[..., None], sizes: tuple[int, ...] | None = None, kinds=KINDS,
        folder: str | os.PathLike | None = None, indices: list[str] | None = None,
        naive_max: int = NAIVE_MAX, timeout: float = 3600.0) -> None:
    """Measure every (size, kind) case in its own subprocess (see the module docstring).

    ``datasets`` is unused (the section generates its field); ``indices`` default to
    every registered index; ``folder`` holds the files while they are measured.
    """
    from ..index import available_indices

    indices = list(indices or available_indices())
    sizes = tuple(sizes or _scale_sizes())
    root = Path(folder or os.environ.get("SPARSECAST_BENCH_SCALE_DIR") or tempfile.gettempdir())
    work = Path(tempfile.mkdtemp(prefix="sparsecast-scale-", dir=root))
    try:
        warm = write_field(WARM_EDGE, work / "warm", kinds)
        for n in sizes:
            t0 = time.perf_counter()
            paths = write_field(n, work / str(n), kinds)
            write_s = time.perf_counter() - t0
            for kind in kinds:
                common = dict(dataset=f"nbody-{n}", size=n, kind=kind, width=width, height=height)
                if kind not in paths:
                    record(**common, method="scale", phase="skipped",
                           reason=f"a dense {kind} copy of {n}^3 float32 does not fit on the disk comfortably")
                    continue
                case = dict(path=str(paths[kind]), warm=str(warm[kind]), kind=kind, width=width, height=height,
                            repeat=repeat, warmup=warmup, indices=indices, naive=n <= naive_max)
                for rec in _child(case, timeout):
                    if rec["phase"] == "load":
                        rec["write_s"] = write_s
                    if rec["phase"] == "skipped" and rec.get("method") == "naive":
                        rec["reason"] = f"naive takes every sample: capped at {naive_max}^3"
                    record(**common, **rec)
            shutil.rmtree(work / str(n), ignore_errors=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _child(case: dict, timeout: float) -> list[dict]:
    """Run one case in a fresh interpreter; its records (the JSON of its last stdout line)."""
    res = subprocess.run([sys.executable, "-m", "sparsecast.bench.scale", json.dumps(case)],
                         capture_output=True, text=True, timeout=timeout, env=os.environ.copy())
    if res.returncode != 0:
        tail = (res.stderr or res.stdout).strip().splitlines()[-1:] or ["no output"]
        return [dict(method="scale", phase="skipped", reason=f"case failed (exit {res.returncode}): {tail[0]}")]
    return json.loads(res.stdout.strip().splitlines()[-1])


def _measure(case: dict) -> list[dict]:
    """One case, in this process (the child's body)."""
    from ..camera import Camera
    from ..index import build_index
    from ..io import load_volume
    from ..render import render
    from ..transfer import TransferFunction

    lazy = True if case["kind"] == "zarr" else None
    w, h = case["width"], case["height"]
    t0 = time.perf_counter()
    vol = load_volume(case["path"], lazy=lazy)
    open_ms = (time.perf_counter() - t0) * 1e3
    t1 = time.perf_counter()
    stats = vol.brick_stats(8)
    stats_wall = (time.perf_counter() - t1) * 1e3
    lo, hi = vol.value_range
    tf = TransferFunction.preset("viridis", (lo, hi), threshold=0.02)
    cam = Camera.orbit(vol, 30.0, 20.0)
    first = render(vol, tf, cam, w, h)  # index="auto"
    first_ms = (time.perf_counter() - t0) * 1e3
    # The statistics pass of a lazy volume ran while opening; a dense one's on first use.
    stats_ms = stats.build_ms if stats_wall < 1.0 else stats_wall
    voxels = int(np.prod(vol.shape, dtype=np.int64))
    occupancy = float(tf.classify_bricks(vol, 8).mean())
    tf2 = TransferFunction.preset("viridis", (lo, hi), threshold=0.2)  # the "TF change"
    out: list[dict] = []
    for name in case["indices"]:
        if name == "naive" and not case["naive"]:
            out.append(dict(method=name, phase="skipped"))
            continue
        idx = build_index(vol, tf, name)
        rebuilt = build_index(vol, tf2, name)
        ms = []
        for i in range(case["warmup"] + case["repeat"]):
            img = render(vol, tf, cam, w, h, index=idx)
            if i >= case["warmup"]:
                ms.append(img.stats["ms"])
        out.append(dict(method=name, phase="render", build_ms=idx.build_ms, rebuild_ms=rebuilt.build_ms,
                        ms=statistics.median(ms), ms_runs=ms, ms_min=min(ms), ms_max=max(ms),
                        samples=int(img.stats["samples"]), bytes=int(idx.nbytes)))
        del idx, rebuilt
    peak = _peak_rss()
    dense = voxels * vol.dtype.itemsize
    bricked = hasattr(vol, "resident_bricks")
    nb = int(np.prod(stats.shape))
    load = dict(method="scale", phase="load", lazy=bool(getattr(vol, "lazy", False)),
                storage="bricked" if bricked else "dense", open_ms=open_ms, stats_ms=stats_ms,
                stats_gvox_s=voxels / (stats_ms * 1e6) if stats_ms > 0 else None, first_image_ms=first_ms,
                first_index=first.stats.get("index"), occupancy=occupancy, bricks=nb,
                peak_rss=int(peak), dense_bytes=int(dense), rss_over_dense=peak / dense,
                resident_bricks=int(vol.resident_bricks) if bricked else nb,
                stored_bricks=int(vol.stored_bricks) if bricked else nb,
                pool_bytes=int(vol.nbytes))
    return [load, *out]


def _peak_rss() -> int:
    """This process's peak resident set in bytes: ``VmHWM`` (the high-water mark of its
    own address space), not ``getrusage``'s ``ru_maxrss``, which Linux carries across
    ``fork`` + ``exec``: a child of a runner that had just written a 4 GiB memory map
    reported the runner's 4.9 GB as its own."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # KiB on Linux


def main(argv: list[str]) -> None:
    """``python -m sparsecast.bench.scale CASE_JSON``: warm up on the case's small file, then
    measure the case; print its records as one JSON line."""
    case = json.loads(argv[0])
    _measure({**case, "path": case["warm"], "width": 16, "height": 16, "repeat": 1, "warmup": 0})
    print(json.dumps(_measure(case), default=float))


if __name__ == "__main__":
    main(sys.argv[1:])
