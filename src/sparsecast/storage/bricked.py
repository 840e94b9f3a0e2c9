"""The :class:`BrickedVolume`: sparse bricked storage, resident on demand under a memory budget.

A bricked volume keeps the voxels of bricks of ``B^3`` cells (``B`` a power of two,
8 by default) in a pool of slots, each with the apron a trilinear sample and a
central-difference gradient need (``(B + 3)^3`` voxels; see
:mod:`sparsecast.kernels.bricked`), and a page table from brick to slot.

* A brick whose every voxel, apron included, equals ``background`` is never
  stored: it reads as the background, exactly.
* Of the others, only those a transfer function can see are *resident*: each
  call of :meth:`BrickedVolume.voxels` with a TF loads the bricks it classifies
  non-empty that are not resident yet (reading only their windows from the
  source), evicting the least recently used bricks the TF does not need when the
  pool is full. A stored brick that is not resident reads as its own minimum,
  which that TF maps to zero opacity (the brick is empty for it), so every
  sample has the opacity it has on the dense volume and the image is the same
  float for float: a zero-opacity sample adds exactly nothing. The iso modes
  test the sign of ``value - iso``, which a brick's minimum shares with every value
  of a brick whose range excludes the isovalue; their resident set is grown by
  one brick so that the refinement and normals near a brick face read real voxels.

Brick statistics are those of the dense volume (``brick_stats(B)`` computed from
the source in one pass, or passed in from a chunk-parallel scan), so every index
builds from them without touching the voxels; indices that look inside bricks
(the deep k-d tree's cell occupancy) read resident bricks through the page table.

The source is anything array-like with ``shape``, ``dtype`` and numpy slicing:
an ndarray, a ``np.memmap``, a Zarr array, an HDF5 dataset. Nothing is ever
written to it.
"""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from .._util.checks import as_int, fail
from ..errors import ParameterError, SparsecastError, VolumeDataError
from ..kernels.bricked import BrickedVoxels, gather_bricks, gather_bricks_serial
from ..kernels.parallel import parallel_section
from ..volume import SUPPORTED_DTYPES, BrickLabels, BrickStats, Volume, check_voxel_shape
from .scan import scan

__all__ = ["BrickedVolume", "MemoryBudgetError", "parse_memory"]

#: voxels a z-slab of :meth:`BrickedVolume.to_dense` reads at a time
_SLAB_VOXELS = 1 << 24


class MemoryBudgetError(ParameterError):
    """The bricks a transfer function needs do not fit in the volume's memory limit."""


def parse_memory(value, name: str = "memory_limit") -> int | None:
    """Bytes from ``None``, an int, or a string such as ``"2GB"``, ``"512 MiB"``, ``"1.5e9"``."""
    if value is None:
        return None
    if isinstance(value, bool):
        raise fail(name, "a size in bytes or a string such as '2GB'", value)
    if isinstance(value, (int, np.integer)):
        n = int(value)
    elif isinstance(value, float) and math.isfinite(value):
        n = int(value)
    elif isinstance(value, str):
        units = {"": 1, "b": 1, "kb": 10**3, "mb": 10**6, "gb": 10**9, "tb": 10**12,
                 "kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40, "k": 10**3, "m": 10**6, "g": 10**9}
        text = value.strip().lower().replace(" ", "")
        num = text.rstrip("abcdefghijklmnopqrstuvwxyz")
        unit = text[len(num):]
        try:
            n = int(float(num) * units[unit])
        except (ValueError, KeyError):
            raise fail(name, "a size such as '2GB', '512MiB' or a number of bytes", value) from None
    else:
        raise fail(name, "a size in bytes or a string such as '2GB'", type(value).__name__)
    if n <= 0:
        raise fail(name, "a positive size", value)
    return n


def _storage_dtype(dtype: np.dtype, name: str) -> np.dtype:
    """The supported dtype the bricks are stored in (lossless for the source's dtype)."""
    dtype = np.dtype(dtype).newbyteorder("=")
    if dtype in SUPPORTED_DTYPES:
        return dtype
    if dtype == np.bool_ or dtype == np.dtype("int8"):
        return np.dtype("int16") if dtype.kind == "i" else np.dtype("uint8")
    if dtype == np.float16:
        return np.dtype("float32")
    if dtype.kind in "iu" and dtype.itemsize <= 4:
        return np.dtype("float64")  # exact for every 32-bit integer
    raise VolumeDataError(
        f"{name!r}: unsupported dtype {dtype}; expected one of {', '.join(str(d) for d in SUPPORTED_DTYPES)} "
        "(or bool, int8, float16, 32-bit integers, which are converted losslessly)"
    )


class BrickedVolume(Volume):
    """A volume stored as non-background bricks, loaded on demand under a memory budget.

    Parameters
    ----------
    source : array_like, shape (nz, ny, nx)
        The voxels: an ndarray, memmap, Zarr array, HDF5 dataset or anything with
        ``shape``, ``dtype`` and numpy slicing. Read only; never modified.
    spacing, origin, name, orientation
        As for :class:`~sparsecast.volume.Volume`.
    brick_size : int, optional
        Cells per brick edge ``B``: a power of two from 8 to 64 (default 8).
    background : float, optional
        The value absent bricks read as (default 0). A brick is absent when every
        voxel of its window (its cells and a one-voxel apron) equals it.
    memory_limit : int or str, optional
        Most bytes the brick pool may take (``"2GB"``; default: no limit). The page
        table and brick statistics (about 24 bytes a brick) come on top.
    stats : BrickStats, optional
        Precomputed ``brick_stats(brick_size)`` of the source (e.g. from a
        chunk-parallel scan); computed from the source when omitted.
    nonfinite : {"raise", "replace"}
        NaN/Inf policy as for :class:`Volume`; "replace" applies when bricks are read.
    eager : bool, optional
        Load every stored brick at once (then the source is no longer needed).
        Default: when ``source`` is an in-memory ndarray and no limit is set.
    progress : bool or callable, optional
        Progress of the statistics pass over a lazy source (see :func:`.scan.scan`).
    value_range : (float, float), optional
        The source's finite value range, when ``stats`` cover only part of it (a piece
        of a volume on a cluster): what ``value_range`` reports and NaN/Inf are replaced
        by. Default: the range of the statistics.

    Examples
    --------
    >>> import numpy as np, sparsecast as sc
    >>> a = np.zeros((40, 40, 40), np.float32); a[10:20, 10:20, 10:20] = 1
    >>> vol = sc.BrickedVolume(a)
    >>> vol.stored_bricks, vol.brick_grid
    (27, (5, 5, 5))
    """

    def __init__(
        self,
        source,
        spacing=1.0,
        origin=0.0,
        *,
        name: str = "volume",
        brick_size: int = 8,
        background: float = 0.0,
        memory_limit: int | str | None = None,
        stats: BrickStats | None = None,
        nonfinite: str = "raise",
        orientation=None,
        eager: bool | None = None,
        progress=None,
        value_range: tuple[float, float] | None = None,
    ) -> None:
        shape = check_voxel_shape(getattr(source, "shape", ()), name)
        B = as_int(brick_size, "brick_size", lo=8, hi=64)
        if B & (B - 1):
            raise fail("brick_size", "a power of two from 8 to 64", brick_size)
        # The base class sets up spacing, origin, orientation and the caches on a
        # stand-in array: the voxels live in the pool, never in ``_data``.
        super().__init__(np.zeros((1, 1, 1), np.uint8), spacing, origin, name=name, nonfinite=nonfinite,
                         orientation=orientation)
        self._source = source
        self._shape = shape
        self._dtype = _storage_dtype(source.dtype, name)
        self._nonfinite = nonfinite
        self._progress = progress
        self._histogram: tuple[np.ndarray, np.ndarray] | None = None
        self.brick_size = B
        self.background = float(background)
        self.memory_limit = parse_memory(memory_limit)
        self._lock = threading.Lock()
        #: what reading from the source cost: bricks loaded, bytes read (statistics
        #: pass included) and milliseconds spent loading bricks
        self.loads: dict[str, float] = {"bricks": 0, "bytes_read": 0, "ms": 0.0}
        nz, ny, nx = shape
        self._grid = tuple(max(1, -(-(n - 1) // B)) for n in shape)
        if stats is None:
            stats = self._scan_stats()
        elif stats.brick_size != B or stats.shape != self._grid:
            raise ParameterError(
                f"stats: brick statistics of {stats.brick_size}^3 bricks on a {stats.shape} grid; "
                f"expected {B}^3 bricks on {self._grid} for shape {shape}"
            )
        self._bricks[B] = stats
        vmin = stats.vmin.ravel()
        vmax = stats.vmax.ravel()
        self._range = (float(vmin.min()), float(vmax.max()))
        if value_range is not None:
            self._range = (float(value_range[0]), float(value_range[1]))
        bg = self.background
        self._stored = ~((vmin == bg) & (vmax == bg))
        self._stored_ids = np.flatnonzero(self._stored)
        n_bricks = vmin.size
        self._pages = np.full(n_bricks, -1, np.int32)
        # A stored brick without a slot reads as its minimum (zero opacity for every TF
        # that does not need it); an absent one as the background.
        self._fill = np.where(self._stored, vmin, bg).astype(np.float64)
        self._last_use = np.zeros(n_bricks, np.int64)
        self._clock = 0
        e = B + 3
        self._brick_bytes = e ** 3 * self._dtype.itemsize
        cap = self._stored_ids.size
        if self.memory_limit is not None:
            cap = min(cap, self.memory_limit // self._brick_bytes)
        self._capacity = int(cap)
        self._pool = np.zeros((0, e, e, e), self._dtype)
        self._slot_brick = np.zeros(0, np.int64)  # brick held by each slot, -1: free
        if eager is None:
            eager = isinstance(source, np.ndarray) and not isinstance(source, np.memmap) and self.memory_limit is None
        if eager:
            if self._stored_ids.size > self._capacity:
                raise self._budget_error(self._stored_ids.size)
            self._load(self._stored_ids)
            if self._dtype.kind in "ui":  # label sets need the voxels: take them while they are here
                self.label_counts()
                for b in sorted({8, B}):
                    self.brick_labels(b)
            self._source = None  # everything that can be read is in the pool

    def __getstate__(self) -> dict:
        # Picklable (a Dask worker may spill a piece to disk or move it): the lock is
        # this process's.
        state = self.__dict__.copy()
        state.pop("_lock", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    # -- what the base class reads from ``_data`` --------------------------
    @property
    def data(self) -> np.ndarray:
        """Not available: the voxels are in bricks. Use :meth:`to_dense` if they fit."""
        raise VolumeDataError(
            f"{self.name}: a bricked volume has no dense array ({self.dense_nbytes / 2**20:.1f} MiB if "
            "materialised); use to_dense() when it fits in memory, or voxels(tf) for rendering"
        )

    @property
    def shape(self) -> tuple[int, int, int]:
        return self._shape  # type: ignore[return-value]

    @property
    def dims(self) -> tuple[int, int, int]:
        nz, ny, nx = self._shape
        return (nx, ny, nz)

    @property
    def dtype(self) -> np.dtype:
        return self._dtype

    @property
    def dense_nbytes(self) -> int:
        """Bytes of the dense array this volume stands for."""
        return int(np.prod(self._shape, dtype=np.int64)) * self._dtype.itemsize

    @property
    def nbytes(self) -> int:
        """Bytes held: the pool's slots, the page table, fills and brick statistics."""
        return int(self._pool.nbytes + self._pages.nbytes + self._fill.nbytes + self._last_use.nbytes
                   + self._stored.nbytes + self._bricks[self.brick_size].nbytes)

    @property
    def brick_grid(self) -> tuple[int, int, int]:
        """Brick counts ``(nbz, nby, nbx)``."""
        return self._grid  # type: ignore[return-value]

    @property
    def stored_bricks(self) -> int:
        """Bricks that are not entirely background."""
        return int(self._stored_ids.size)

    @property
    def resident_bricks(self) -> int:
        """Bricks in the pool now."""
        return int(np.count_nonzero(self._pages >= 0))

    @property
    def nonfinite(self) -> str:
        """The NaN/Inf policy bricks are read with (``"raise"`` or ``"replace"``)."""
        return self._nonfinite

    @property
    def lazy(self) -> bool:
        """Whether bricks are still read from the source on demand."""
        return self._source is not None

    def __repr__(self) -> str:
        nx, ny, nz = self.dims
        limit = f", memory_limit={self.memory_limit}" if self.memory_limit is not None else ""
        return (f"BrickedVolume(name={self.name!r}, dims={nx}x{ny}x{nz}, dtype={self.dtype}, "
                f"brick_size={self.brick_size}, stored={self.stored_bricks}/{self._stored.size}, "
                f"resident={self.resident_bricks}{limit})")

    # -- rendering ----------------------------------------------------------
    def voxels(self, tf=None, *, mode: str = "dvr") -> BrickedVoxels:
        """The kernel-side page table and pool with every brick ``tf`` can see resident.

        Parameters
        ----------
        tf : TransferFunction, optional
            The classification TF of the frame (for the iso modes, the spiked TF of
            :func:`~sparsecast.render.api.classification_tf`). None: every stored brick.
        mode : {"dvr", "iso", "iso+dvr"}
            The iso modes grow the resident set by one brick (see the module docstring).

        Raises
        ------
        MemoryBudgetError
            The needed bricks do not fit in ``memory_limit``; says how much they need.
        """
        need = self._stored.copy() if tf is None else (tf.classify_bricks(self, self.brick_size).ravel()
                                                       & self._stored)
        if mode != "dvr":
            need = _dilate(need.reshape(self._grid)).ravel() & self._stored
        ids = np.flatnonzero(need)
        with self._lock:
            if ids.size > self._capacity:
                raise self._budget_error(ids.size)
            self._clock += 1
            self._last_use[ids] = self._clock
            missing = ids[self._pages[ids] < 0]
            if missing.size:
                if self._source is None:
                    raise VolumeDataError(f"{self.name}: bricks are missing and the source is gone")
                self._load(missing)
        nbz, nby, nbx = self._grid
        nz, ny, nx = self._shape
        return BrickedVoxels(self._pool.reshape(-1), self._pages, self._fill, nx, ny, nz, nbx, nby,
                             int(self.brick_size).bit_length() - 1)

    def to_dense(self) -> np.ndarray:
        """The dense ``(nz, ny, nx)`` array (reads every stored brick that is not resident)."""
        nz, ny, nx = self._shape
        return self.read_window(0, nz, 0, ny, 0, nx)

    def read_window(self, z0: int, z1: int, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        """Voxels ``[z0, z1) x [y0, y1) x [x0, x1)`` as a new array (from the source when
        there is one, else from the stored bricks; absent bricks read as the background).
        A piece of a volume on a cluster is cut with it, without the whole dense array."""
        nz, ny, nx = self._shape
        z0, y0, x0 = max(int(z0), 0), max(int(y0), 0), max(int(x0), 0)
        z1, y1, x1 = min(int(z1), nz), min(int(y1), ny), min(int(x1), nx)
        out = np.full((max(z1 - z0, 0), max(y1 - y0, 0), max(x1 - x0, 0)), self.background, self._dtype)
        if out.size == 0:
            return out
        B = self.brick_size
        nbz, nby, nbx = self._grid
        if self._source is not None:
            step = max(1, _SLAB_VOXELS // ((y1 - y0) * (x1 - x0)))
            for z in range(z0, z1, step):
                out[z - z0:min(z1, z + step) - z0] = self._read(z, min(z1, z + step), y0, y1, x0, x1)
            return out
        # Brick b holds voxels b*B .. b*B + B in its slot (from offset 1: the apron before them).
        for b in self._stored_ids:
            bz, rem = divmod(int(b), nby * nbx)
            by, bx = divmod(rem, nbx)
            lo = [max(c * B, w0) for c, w0 in ((bz, z0), (by, y0), (bx, x0))]
            hi = [min(c * B + B, n - 1, w1 - 1) for c, n, w1 in ((bz, nz, z1), (by, ny, y1), (bx, nx, x1))]
            if any(a > h for a, h in zip(lo, hi)):
                continue
            block = self._pool[self._pages[b]]
            out[lo[0] - z0:hi[0] - z0 + 1, lo[1] - y0:hi[1] - y0 + 1, lo[2] - x0:hi[2] - x0 + 1] = block[
                lo[0] - bz * B + 1:hi[0] - bz * B + 2, lo[1] - by * B + 1:hi[1] - by * B + 2,
                lo[2] - bx * B + 1:hi[2] - bx * B + 2]
        return out

    # -- statistics -----------------------------------------------------------
    def histogram(self, bins: int = 64) -> tuple[np.ndarray, np.ndarray]:
        """``(counts, edges)`` over :attr:`value_range`: exact when the statistics came
        from a scan of the source (rebinned to ``bins`` when they divide), else from the
        stored bricks (each voxel of an absent brick counted as the background)."""
        lo, hi = self.value_range
        if not hi > lo:
            hi = lo + 1.0
        if self._histogram is not None and len(self._histogram[0]) % bins == 0:
            counts = self._histogram[0].reshape(bins, -1).sum(axis=1)
            return counts, np.linspace(lo, hi, bins + 1)
        counts = np.zeros(bins, np.int64)
        resident = np.flatnonzero(self._pages >= 0)
        if resident.size:
            inner = self._pool[self._pages[resident]][:, 1:-2, 1:-2, 1:-2]  # cells' voxels, apron off
            counts += np.histogram(inner, bins=bins, range=(lo, hi))[0]
        B3 = self.brick_size ** 3
        absent = int(self._stored.size - self._stored_ids.size)
        if absent:
            counts += np.histogram([self.background], bins=bins, range=(lo, hi))[0] * (absent * B3)
        return counts, np.linspace(lo, hi, bins + 1)

    def brick_stats(self, brick_size: int = 8) -> BrickStats:
        """Per-brick min/max with apron; ``brick_size`` a multiple or a divisor of ``B``.

        Multiples are reduced from the stored statistics (exact). Divisors are computed
        from resident bricks (exact there) and take the range of their storage brick
        where it is not resident (a superset: conservative for every index).
        """
        brick_size = as_int(brick_size, "brick_size", lo=1)
        cached = self._bricks.get(brick_size)
        if cached is not None:
            return cached
        B = self.brick_size
        t0 = time.perf_counter()
        base = self._bricks[B]
        if brick_size % B == 0:
            f = brick_size // B
            shape = tuple(max(1, -(-(n - 1) // brick_size)) for n in self._shape)
            vmin = _reduce(base.vmin, f, np.minimum, shape)
            vmax = _reduce(base.vmax, f, np.maximum, shape)
        elif B % brick_size == 0:
            vmin, vmax = self._sub_brick_stats(brick_size)
        else:
            raise ParameterError(
                f"brick_size: {brick_size} on a volume stored in {B}^3 bricks; expected a multiple or a "
                f"divisor of {B}"
            )
        stats = BrickStats(brick_size, vmin, vmax, (time.perf_counter() - t0) * 1e3)
        self._bricks[brick_size] = stats
        return stats

    def brick_labels(self, brick_size: int = 8) -> BrickLabels | None:
        """Per-brick label sets when the source is an in-memory or memory-mapped array
        (an eager volume keeps those of 8^3 and ``B^3`` bricks), else None: label TFs
        then classify bricks by value range, which is conservative."""
        if brick_size in self._labels:
            return self._labels[brick_size]
        dense = self._dense_source()
        if dense is None:
            return None
        self._labels[brick_size] = dense.brick_labels(brick_size)
        return self._labels[brick_size]

    def label_counts(self):
        if self._ids is False:
            dense = self._dense_source()
            if dense is None:
                return None
            self._ids = dense.label_counts()
        return self._ids

    # -- internals ---------------------------------------------------------------
    def _dense_source(self) -> Volume | None:
        src = self._source
        if not isinstance(src, np.ndarray):
            return None
        if not hasattr(self, "_dense_view"):
            self._dense_view = Volume(src.astype(self._dtype, copy=False), name=self.name, nonfinite="replace")
        return self._dense_view

    def _budget_error(self, n_needed: int) -> MemoryBudgetError:
        need = n_needed * self._brick_bytes
        return MemoryBudgetError(
            f"memory_limit: {self.name} needs {n_needed} bricks of {self.brick_size}^3 cells "
            f"({need / 2**20:.1f} MiB) resident for this transfer function, but memory_limit="
            f"{self.memory_limit} bytes ({(self.memory_limit or 0) / 2**20:.1f} MiB) holds "
            f"{self._capacity}; raise memory_limit to at least {math.ceil(need / 2**20 * 10) / 10:.1f} MiB or make the TF sparser"
        )

    def _read(self, z0, z1, y0, y1, x0, x1) -> np.ndarray:
        """Voxels ``[z0, z1) x [y0, y1) x [x0, x1)`` of the source, in the storage dtype."""
        try:
            block = np.asarray(self._source[z0:z1, y0:y1, x0:x1])
        except (SparsecastError, MemoryError):
            raise  # the source's own error names its chunk; memory is no fault of the source's
        except Exception as exc:  # a reader's own error: name the store and the region
            raise VolumeDataError(
                f"{self.name}: reading voxels z {z0}:{z1}, y {y0}:{y1}, x {x0}:{x1} failed: "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        self.loads["bytes_read"] += block.nbytes
        block = block.astype(self._dtype, copy=False)
        if block.dtype.kind == "f" and not np.isfinite(block).all():
            if self._nonfinite == "raise":
                raise VolumeDataError(
                    f"{self.name}: NaN or Inf in voxels z {z0}:{z1}, y {y0}:{y1}, x {x0}:{x1}; expected finite "
                    "values (pass nonfinite='replace', on the command line --nonfinite replace)"
                )
            lo, hi = self._range if self._range is not None else (0.0, 0.0)
            block = np.nan_to_num(block, nan=lo, posinf=hi, neginf=lo)
        return block

    def _scan_stats(self) -> BrickStats:
        """``brick_stats(B)`` of the source: the dense kernel for an in-memory array, else
        one chunk-parallel pass (:func:`.scan.scan`) that also keeps a histogram."""
        src = self._source
        B = self.brick_size
        if isinstance(src, np.ndarray) and src.dtype in SUPPORTED_DTYPES and not isinstance(src, np.memmap):
            return Volume(src, name=self.name, nonfinite=self._nonfinite).brick_stats(B)
        try:
            found = scan(src, B, nonfinite=self._nonfinite, progress=self._progress)
        except (SparsecastError, MemoryError):
            raise  # a source's own errors name its chunks
        except Exception as exc:  # an array-like's reader failing: name the volume
            raise VolumeDataError(f"{self.name}: reading the source failed: {type(exc).__name__}: {exc}") from exc
        self.loads["bytes_read"] += found.shape[0] * found.shape[1] * found.shape[2] * found.dtype.itemsize
        self._histogram = (found.counts, found.edges) if found.counts is not None else None
        self._range = found.value_range  # finite range: what "replace" substitutes
        return found.brick_stats()

    def _sub_brick_stats(self, b: int) -> tuple[np.ndarray, np.ndarray]:
        B = self.brick_size
        f = B // b
        shape = tuple(max(1, -(-(n - 1) // b)) for n in self._shape)
        base = self._bricks[B]
        # Start from the storage brick's range (a superset), refine resident ones exactly.
        vmin = np.repeat(np.repeat(np.repeat(base.vmin, f, 0), f, 1), f, 2)[: shape[0], : shape[1], : shape[2]].copy()
        vmax = np.repeat(np.repeat(np.repeat(base.vmax, f, 0), f, 1), f, 2)[: shape[0], : shape[1], : shape[2]].copy()
        nz, ny, nx = self._shape
        nbz, nby, nbx = self._grid
        for sb in np.flatnonzero(self._pages >= 0):
            bz, rem = divmod(int(sb), nby * nbx)
            by, bx = divmod(rem, nbx)
            blk = self._pool[self._pages[sb]]
            for cz in range(f):
                gz = bz * f + cz
                if gz >= shape[0]:
                    continue
                for cy in range(f):
                    gy = by * f + cy
                    if gy >= shape[1]:
                        continue
                    for cx in range(f):
                        gx = bx * f + cx
                        if gx >= shape[2]:
                            continue
                        # window [g*b - 1, (g+1)*b + 1] clipped, in slot coordinates (+1 - B*brick)
                        lo = [max(g * b - 1, 0) - s * B + 1 for g, s in ((gz, bz), (gy, by), (gx, bx))]
                        hi = [min((g + 1) * b + 1, n - 1) - s * B + 1
                              for g, s, n in ((gz, bz, nz), (gy, by, ny), (gx, bx, nx))]
                        w = blk[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1]
                        vmin[gz, gy, gx] = float(w.min())
                        vmax[gz, gy, gx] = float(w.max())
        return vmin, vmax

    def _grow(self, n_slots: int) -> None:
        """Grow the pool to ``n_slots`` slots (geometrically, up to the capacity)."""
        have = self._pool.shape[0]
        if n_slots <= have:
            return
        if self.memory_limit is not None:
            # The budget is the pool's size: take it at once (zeros are mapped lazily, so
            # untouched slots cost no resident memory) rather than growing by copies, which
            # would hold the old and the new pool together, up to twice the budget.
            n = self._capacity
        else:
            n = min(self._capacity, max(n_slots, int(have * 1.5) + 16))
        e = self.brick_size + 3
        pool = np.zeros((n, e, e, e), self._dtype)
        pool[:have] = self._pool
        self._pool = pool
        self._slot_brick = np.concatenate([self._slot_brick, np.full(n - have, -1, np.int64)])

    def _take_slots(self, n: int) -> np.ndarray:
        """``n`` free slots, evicting least recently used bricks not used by this call."""
        free = np.flatnonzero(self._slot_brick < 0)
        if free.size < n:
            self._grow(self._pool.shape[0] + n - free.size)
            free = np.flatnonzero(self._slot_brick < 0)
        if free.size < n:
            held = self._slot_brick[self._slot_brick >= 0]
            # Bricks stamped with the current clock are needed now and stay.
            old = held[self._last_use[held] < self._clock]
            victims = old[np.argsort(self._last_use[old], kind="stable")][: n - free.size]
            slots = self._pages[victims]
            self._pages[victims] = -1
            self._slot_brick[slots] = -1
            free = np.flatnonzero(self._slot_brick < 0)
        return free[:n]

    def _load(self, bricks: np.ndarray) -> None:
        """Read the windows of ``bricks`` from the source into free slots."""
        t0 = time.perf_counter()
        slots = self._take_slots(bricks.size)
        B = self.brick_size
        nz, ny, nx = self._shape
        nbz, nby, nbx = self._grid
        bz, rem = np.divmod(bricks, nby * nbx)
        by, bx = np.divmod(rem, nbx)
        src = self._source
        if (isinstance(src, np.ndarray) and src.dtype == self._dtype
                and (src.dtype.kind != "f" or self._nonfinite == "raise")):
            # In memory (or mapped) already, and checked finite by the statistics pass:
            # copy the windows straight out of it.
            with parallel_section():
                gather_bricks(src, 0, 0, 0, bz, by, bx, slots.astype(np.int64), B, nz, ny, nx, self._pool)
        else:
            self._load_blocks(bz, by, bx, slots)
        self._pages[bricks] = slots.astype(np.int32)
        self._slot_brick[slots] = bricks
        self.loads["bricks"] += bricks.size
        self.loads["ms"] += (time.perf_counter() - t0) * 1e3

    def _load_blocks(self, bz, by, bx, slots) -> None:
        """Group bricks into blocks aligned to the source's chunks and read each block once."""
        B = self.brick_size
        nz, ny, nx = self._shape
        chunks = getattr(self._source, "chunks", None)
        if not (isinstance(chunks, tuple) and len(chunks) == 3 and all(isinstance(c, int) for c in chunks)):
            chunks = (64, 64, 64)
        # Block edge in bricks: the source chunk rounded up to whole bricks (at least 4 bricks).
        per = [max(4, -(-int(c) // B)) for c in chunks]
        key = (bz // per[0]) * (1 << 42) + (by // per[1]) * (1 << 21) + (bx // per[2])
        order = np.argsort(key, kind="stable")
        keys = key[order]
        cuts = np.flatnonzero(np.diff(keys)) + 1
        groups = np.split(order, cuts)

        def one(g: np.ndarray) -> None:
            z0 = max(int(bz[g].min()) * B - 1, 0)
            y0 = max(int(by[g].min()) * B - 1, 0)
            x0 = max(int(bx[g].min()) * B - 1, 0)
            z1 = min(int(bz[g].max()) * B + B + 1, nz - 1) + 1
            y1 = min(int(by[g].max()) * B + B + 1, ny - 1) + 1
            x1 = min(int(bx[g].max()) * B + B + 1, nx - 1) + 1
            block = self._read(z0, z1, y0, y1, x0, x1)  # reads overlap across threads
            gather_bricks_serial(block, z0, y0, x0, bz[g], by[g], bx[g], slots[g].astype(np.int64), B, nz, ny, nx,
                                 self._pool)

        with ThreadPoolExecutor(max_workers=2) as pool:
            list(pool.map(one, groups))


def _dilate(flags: np.ndarray) -> np.ndarray:
    """``flags`` grown by one brick in all 26 directions."""
    from scipy.ndimage import binary_dilation  # scipy is a dependency; imported where used

    return binary_dilation(flags, structure=np.ones((3, 3, 3), bool))


def _reduce(a: np.ndarray, f: int, op, shape) -> np.ndarray:
    pad = [(0, s * f - n) for s, n in zip(shape, a.shape)]
    fill = np.inf if op is np.minimum else -np.inf
    a = np.pad(a, pad, constant_values=fill)
    nz, ny, nx = shape
    return op.reduce(op.reduce(op.reduce(a.reshape(nz, f, ny, f, nx, f), axis=5), axis=3), axis=1)
