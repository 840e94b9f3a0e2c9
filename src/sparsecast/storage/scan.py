"""One chunk-parallel pass over a volume that need not fit in memory: :func:`scan`.

The pass yields what :class:`~sparsecast.volume.Volume` computes from a dense array
before anything is rendered: the value range, a histogram, the NaN/Inf check and the
per-brick min/max with the one-voxel apron, equal bit for bit to
``Volume(arr).brick_stats(B)``.

How
---
``dask.array`` splits the source along its own chunks (merged into blocks of a few
MiB) and the threaded scheduler runs one task per block on ``workers`` threads. Brick
``b`` covers voxels ``[bB - 1, (b+1)B + 1]`` (clipped) on each axis, so bricks at a
block face need voxels of the neighbouring block. Rather than read overlaps
(``map_overlap``), each block reduces the *part* of every brick window that lies inside
it (:func:`~sparsecast.kernels.windows.window_minmax`) and the partial ranges are
combined with ``min`` / ``max`` into the brick arrays under a lock. Min and max are
exact and order-free, so the result does not depend on the chunking; the value range
is the range of the brick ranges (the windows cover every voxel).

Float blocks holding NaN/Inf follow the dense policy: ``"raise"`` counts them all and
raises naming the count; ``"replace"`` computes the brick ranges as the dense path
does after ``nan_to_num(nan=min, neginf=min, posinf=max)`` with the finite min/max,
which are only known at the end: each block reduces its finite values and flags the
bricks that held a low (NaN, -Inf) or high (+Inf) non-finite voxel, and the flags are
resolved against the final range.

Histograms of 8- and 16-bit integers are exact value counts in the same pass, rebinned
at the end; other dtypes (floats) take a second pass over the blocks once the range is
known. Either way the counts equal ``np.histogram(data, bins, range=value_range)``.
Memory: the brick arrays, one histogram, and a block per worker in flight.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from .._util.checks import as_int, one_of
from .._util.progress import ProgressArg, chunk_progress
from ..errors import VolumeDataError
from ..kernels.bricks import brick_windows
from ..kernels.windows import count_values_nogil, window_minmax
from ..volume import BrickStats, check_voxel_shape, nonfinite_error

__all__ = ["Scan", "scan", "scan_blocks"]

#: bytes a block of the scan aims at: large enough that per-task overhead vanishes,
#: small enough that ``workers`` blocks in flight are a small fraction of memory
BLOCK_BYTES = 8 << 20
#: bytes of one z-slice of a block of contiguous data (see :func:`scan_blocks`)
PLANE_BYTES = 256 << 10


@dataclass(frozen=True)
class Scan:
    """What one pass over a volume found.

    Attributes
    ----------
    shape : (nz, ny, nx)
        The volume's shape.
    dtype : numpy.dtype
        The voxels' dtype.
    brick_size : int
        Cells per brick edge ``B``.
    vmin, vmax : ndarray of float64, shape (nbz, nby, nbx)
        Per-brick range with the one-voxel apron (as :meth:`Volume.brick_stats`),
        after the non-finite policy.
    value_range : (float, float)
        Min and max of the voxels (of the finite ones, non-finite voxels replaced).
    counts : ndarray of int64, shape (bins,) or None
        Histogram counts over ``edges``; None when ``bins=0``.
    edges : ndarray of float64, shape (bins + 1,) or None
        ``np.histogram``'s bin edges over ``value_range``.
    nan, posinf, neginf : int
        Non-finite voxels found (0 for integer data).
    blocks : tuple of tuple of int
        The block sizes along each axis (dask's ``chunks``).
    build_ms : float
        Wall time of the pass (kernel compilation excluded).
    """

    shape: tuple[int, int, int]
    dtype: np.dtype
    brick_size: int
    vmin: np.ndarray
    vmax: np.ndarray
    value_range: tuple[float, float]
    counts: np.ndarray | None
    edges: np.ndarray | None
    nan: int
    posinf: int
    neginf: int
    blocks: tuple[tuple[int, ...], ...]
    build_ms: float

    @property
    def nonfinite(self) -> int:
        """NaN and Inf voxels together."""
        return self.nan + self.posinf + self.neginf

    def brick_stats(self) -> BrickStats:
        """The brick ranges as a :class:`~sparsecast.volume.BrickStats`."""
        return BrickStats(self.brick_size, self.vmin, self.vmax, self.build_ms)


def _array_of(volume) -> tuple[Any, str, tuple[int, ...] | None]:
    """``(array-like, name for messages, native chunk shape or None)`` of a Source,
    a dask array, a zarr/h5py array or an ndarray."""
    array = getattr(volume, "array", volume)  # a Source holds its array
    name = str(getattr(volume, "path", None) or getattr(volume, "name", None) or "array")
    chunks = getattr(volume, "chunks", None)
    if chunks is not None and not all(isinstance(c, (int, np.integer)) for c in chunks):
        chunks = tuple(c[0] for c in chunks)  # a dask array's chunks: the regular size
    if not hasattr(array, "shape") or not hasattr(array, "dtype"):
        array = np.asarray(array)
    check_voxel_shape(array.shape, name)
    return array, name, (tuple(int(c) for c in chunks) if chunks is not None else None)


class _Sliced:
    """An ndarray (or a minimal array-like) seen by dask as an opaque array-like: blocks are
    read when a task runs (``from_array`` copies every block of an ndarray up front)."""

    def __init__(self, array) -> None:
        self.shape, self.dtype, self.ndim = tuple(array.shape), np.dtype(array.dtype), len(array.shape)
        self._array = array

    def __getitem__(self, key) -> np.ndarray:
        return self._array[key]


def scan_blocks(shape, itemsize: int, chunks: tuple[int, ...] | None,
                target: int = BLOCK_BYTES) -> tuple[int, int, int]:
    """Block shape for a pass over an array: whole chunks of the store (a chunk is read
    and decoded once), grown along x, then y, then z while the block stays under
    ``target`` bytes; a contiguous array (``chunks=None``) in slabs of whole rows."""
    nz, ny, nx = (int(n) for n in shape)
    if chunks is None:
        # Whole rows; at most PLANE_BYTES of a plane, so the kernel's reduced planes stay
        # in cache while the block's z-slices stream past them; then as many planes as fit.
        rows = max(1, min(ny, PLANE_BYTES // max(1, nx * itemsize)))
        planes = max(1, min(nz, target // (rows * nx * itemsize)))
        return (planes, rows, nx)
    base = [max(1, min(int(c), int(n))) for c, n in zip(chunks, shape)]
    for axis in (2, 1, 0):
        while base[axis] < shape[axis]:
            grown = min(base[axis] + chunks[axis], int(shape[axis]))
            if math.prod(base) // base[axis] * grown * itemsize > target:
                break
            base[axis] = grown
    return tuple(base)  # type: ignore[return-value]


def _block_windows(lo: np.ndarray, hi: np.ndarray, c0: int, c1: int):
    """The bricks whose windows meet voxels ``[c0, c1)``: ``(slice of bricks, local lo, local hi)``."""
    first = int(np.searchsorted(hi, c0, side="left"))       # first window reaching c0
    last = int(np.searchsorted(lo, c1 - 1, side="right"))   # windows starting at or before c1-1
    sel = slice(first, last)
    return sel, np.maximum(lo[sel], c0) - c0, np.minimum(hi[sel], c1 - 1) - c0


class _Accumulator:
    """The brick arrays, counts and flags every block task folds its partial results into."""

    def __init__(self, nb: tuple[int, int, int], dtype: np.dtype, bins: int):
        self.lock = threading.Lock()
        self.vmin = np.full(nb, np.inf)
        self.vmax = np.full(nb, -np.inf)
        self.low: np.ndarray | None = None    # bricks holding NaN or -Inf (replace policy)
        self.high: np.ndarray | None = None   # bricks holding +Inf
        self.nan = self.posinf = self.neginf = 0
        self.values: np.ndarray | None = None
        self.value_lo = 0
        if bins and dtype.kind in "ui" and dtype.itemsize <= 2:
            info = np.iinfo(dtype)
            self.value_lo = int(info.min)
            self.values = np.zeros(int(info.max) - int(info.min) + 1, np.int64)

    def fold(self, box, pmin, pmax, low=None, high=None, values=None, bad=(0, 0, 0)) -> None:
        with self.lock:
            np.minimum(self.vmin[box], pmin, out=self.vmin[box])
            np.maximum(self.vmax[box], pmax, out=self.vmax[box])
            if low is not None:
                if self.low is None:
                    self.low = np.zeros(self.vmin.shape, bool)
                    self.high = np.zeros(self.vmin.shape, bool)
                self.low[box] |= low
                self.high[box] |= high
            if values is not None:
                self.values += values
            self.nan += bad[0]
            self.posinf += bad[1]
            self.neginf += bad[2]


def scan(
    volume,
    brick_size: int = 8,
    *,
    bins: int = 256,
    nonfinite: Literal["raise", "replace"] = "raise",
    progress: ProgressArg = None,
    workers: int = 2,
) -> Scan:
    """Value range, histogram, NaN/Inf check and brick ranges in one chunk-parallel pass.

    Parameters
    ----------
    volume : Source, dask array, or array-like of shape (nz, ny, nx)
        A :class:`~sparsecast.io.sources.Source` (its ``array`` and ``chunks``), a zarr
        or h5py array, a memory map or an ndarray: anything with ``shape``, ``dtype``
        and basic slicing. Never read whole: one block per worker at a time.
    brick_size : int, optional
        Cells per brick edge ``B`` (default 8).
    bins : int, optional
        Histogram bins over the value range (default 256; 0: no histogram).
    nonfinite : {"raise", "replace"}, optional
        The dense :class:`~sparsecast.volume.Volume`'s NaN/Inf policy: raise naming the
        count (default), or report the counts and give the statistics of the volume
        with NaN and -Inf replaced by the finite minimum and +Inf by the maximum.
    progress : bool or callable, optional
        True: a progress bar on stderr; a callable: ``progress(done, total)`` per block.
    workers : int, optional
        Threads of dask's threaded scheduler (default 2).

    Returns
    -------
    Scan
        ``scan.vmin`` / ``scan.vmax`` equal ``Volume(arr).brick_stats(B).vmin`` / ``vmax``.

    Raises
    ------
    VolumeDataError
        Not 3-D, a zero-size axis, NaN/Inf under ``"raise"`` (naming the count), or
        only non-finite voxels.
    ParameterError
        A bad ``brick_size``, ``bins``, ``nonfinite`` or ``workers``.
    FileFormatError
        A chunk of the source is missing or corrupt (from the source's reader).
    """
    import dask
    import dask.array as da

    brick_size = as_int(brick_size, "brick_size", lo=1)
    bins = as_int(bins, "bins", lo=0)
    workers = as_int(workers, "workers", lo=1)
    one_of(nonfinite, "nonfinite", ("raise", "replace"), expected="'raise' or 'replace'")
    array, name, native = _array_of(volume)
    shape = tuple(int(n) for n in array.shape)
    dtype = np.dtype(array.dtype)
    if dtype.kind not in "uif":
        raise VolumeDataError(f"{name!r}: dtype {dtype} is not a real number type; expected integers or floats")
    if isinstance(array, da.Array):
        darr = array
    else:
        if isinstance(array, np.ndarray) or not hasattr(array, "ndim"):
            # dask would copy an ndarray's blocks when the graph is built, and needs
            # ``ndim``, which a minimal array-like (shape, dtype, slicing) may lack
            array = _Sliced(array)
        block = scan_blocks(shape, dtype.itemsize, native)
        # lock=False: the sources are read-only and their readers thread-safe (h5py
        # serialises itself); asarray=False keeps the source's own reads lazy.
        darr = da.from_array(array, chunks=block, lock=False, asarray=False, fancy=False,
                             name=f"scan-source-{id(array):x}-{time.monotonic_ns()}")
    wins = [brick_windows(n, brick_size) for n in shape]
    nb = tuple(len(w[0]) for w in wins)
    offsets = [np.concatenate(([0], np.cumsum(c))) for c in darr.chunks]
    acc = _Accumulator(nb, dtype, bins)
    is_float = dtype.kind == "f"
    _warm(dtype)

    def reduce_block(block, index, tick):
        block = np.ascontiguousarray(block)
        box, local = [], []
        for axis, i in enumerate(index):
            sel, lo, hi = _block_windows(*wins[axis], int(offsets[axis][i]), int(offsets[axis][i + 1]))
            box.append(sel)
            local += [lo, hi]
        box = tuple(box)
        out_shape = tuple(s.stop - s.start for s in box)
        pmin = np.empty(out_shape)
        pmax = np.empty(out_shape)
        values = None
        if acc.values is not None:
            values = np.zeros_like(acc.values)
            count_values_nogil(block, acc.value_lo, values)
        if is_float and not (np.isfinite(block.min()) and np.isfinite(block.max())):
            # NaN propagates through min/max, so two fast reductions find a bad block.
            nan = np.isnan(block)
            pos = np.isposinf(block)
            neg = np.isneginf(block)
            bad = (int(nan.sum()), int(pos.sum()), int(neg.sum()))
            if nonfinite == "raise":
                acc.fold(box, np.inf, -np.inf, bad=bad)
            else:
                low = (nan | neg).astype(np.uint8)
                finite = ~(nan | neg | pos)
                window_minmax(np.where(finite, block, np.inf), *local, pmin, np.empty(out_shape))
                window_minmax(np.where(finite, block, -np.inf), *local, np.empty(out_shape), pmax)
                low_b, high_b = np.empty(out_shape), np.empty(out_shape)
                window_minmax(low, *local, np.empty(out_shape), low_b)
                window_minmax(pos.view(np.uint8), *local, np.empty(out_shape), high_b)
                acc.fold(box, pmin, pmax, low_b > 0, high_b > 0, values, bad)
        else:
            window_minmax(block, *local, pmin, pmax)
            acc.fold(box, pmin, pmax, values=values)
        tick.advance()

    t0 = time.perf_counter()
    blocks = darr.to_delayed()
    with chunk_progress(progress, blocks.size, f"scan {name}") as tick:
        tasks = [dask.delayed(reduce_block, pure=False)(blocks[idx], idx, tick)
                 for idx in np.ndindex(blocks.shape)]
        dask.compute(*tasks, scheduler="threads", num_workers=workers)
    n_bad = acc.nan + acc.posinf + acc.neginf
    if n_bad and nonfinite == "raise":
        raise nonfinite_error(name, n_bad)
    vmin, vmax = acc.vmin, acc.vmax
    finite = np.isfinite(vmin)
    if not finite.any():
        raise nonfinite_error(name, n_bad, every=True)
    lo, hi = float(vmin[finite].min()), float(vmax[np.isfinite(vmax)].max())
    if acc.low is not None:
        # The dense path replaces NaN/-Inf by lo and +Inf by hi before its brick pass.
        vmin = np.where(acc.low, np.minimum(vmin, lo), vmin)
        vmin = np.where(acc.high, np.minimum(vmin, hi), vmin)
        vmax = np.where(acc.high, np.maximum(vmax, hi), vmax)
        vmax = np.where(acc.low, np.maximum(vmax, lo), vmax)
    counts = edges = None
    if bins:
        if acc.values is not None:
            present = np.flatnonzero(acc.values)
            counts, edges = np.histogram(present + acc.value_lo, bins, range=(lo, hi),
                                         weights=acc.values[present])
        else:
            counts, edges = _histogram_pass(darr, bins, lo, hi, nonfinite == "replace" and n_bad > 0,
                                            workers, progress, name)
        counts = counts.astype(np.int64)
    ms = (time.perf_counter() - t0) * 1e3
    return Scan(shape, dtype, brick_size, vmin, vmax, (lo, hi), counts, edges,
                acc.nan, acc.posinf, acc.neginf, tuple(tuple(c) for c in darr.chunks), ms)


def _histogram_pass(darr, bins: int, lo: float, hi: float, replace: bool, workers: int,
                    progress: ProgressArg, name: str) -> tuple[np.ndarray, np.ndarray]:
    """``np.histogram(data, bins, range=(lo, hi))`` summed block by block (bin edges and the
    bin of every value are those of the one dense call)."""
    import dask

    lock = threading.Lock()
    total = np.zeros(bins, np.int64)

    def count(block, tick):
        block = np.asarray(block)
        if replace:
            block = np.nan_to_num(block, nan=lo, posinf=hi, neginf=lo)
        c, _ = np.histogram(block, bins, range=(lo, hi))
        with lock:
            total[:] += c
        tick.advance()

    blocks = darr.to_delayed()
    with chunk_progress(progress, blocks.size, f"histogram {name}") as tick:
        dask.compute(*[dask.delayed(count, pure=False)(b, tick) for b in blocks.ravel()],
                     scheduler="threads", num_workers=workers)
    return total, np.histogram_bin_edges(np.empty(0, darr.dtype), bins, range=(lo, hi))


_WARM: set[str] = set()


def _warm(dtype: np.dtype) -> None:
    """Compile (or load from the cache) the block kernels for ``dtype`` on a tiny block,
    once per process, so that the pass's time excludes compilation."""
    if dtype.str in _WARM:
        return
    w = np.zeros(1, np.int64)
    out = np.empty((1, 1, 1))
    # Blocks are writable copies or read-only views of a memory map: Numba types the
    # two apart, so both are compiled here.
    for writable in (True, False):
        tiny = np.zeros((2, 2, 2), dtype)
        tiny.setflags(write=writable)
        window_minmax(tiny, w, w, w, w, w, w, out, out)
        if dtype.kind in "ui" and dtype.itemsize <= 2:
            count_values_nogil(tiny, 0, np.zeros(2, np.int64))
    window_minmax(np.zeros((2, 2, 2), np.uint8), w, w, w, w, w, w, out, out)  # the NaN/Inf flags
    _WARM.add(dtype.str)
