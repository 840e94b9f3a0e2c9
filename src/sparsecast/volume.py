"""The :class:`Volume`: a scalar voxel array with spacing and origin.

Index space follows VTK image data / OSPRay structured volumes: voxel ``(i, j, k)``
is the sample at point ``(x=i, y=j, z=k)``; the domain is the box
``[0, nx-1] x [0, ny-1] x [0, nz-1]`` and ``world = origin + spacing * index``.
Arrays are C-ordered with shape ``(nz, ny, nx)`` and indexed ``[k, j, i]``. World axes
are index axes (no direction cosines), so a volume's anatomical ``orientation`` (axis
codes, see :mod:`sparsecast.axes`) names where world +x, +y, +z point in the patient.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from collections.abc import Hashable
from typing import Any, Literal

import numpy as np

from .kernels.parallel import parallel_section
from ._util.checks import as_int, one_of, vector3
from .axes import Orientation, check_orientation
from .errors import VolumeDataError
from .kernels.bricks import brick_ranges, warm_brick_ranges
from .kernels.label_sets import brick_label_words, count_values

__all__ = ["Volume", "BrickStats", "SUPPORTED_DTYPES"]

#: dtypes the renderers are compiled for; anything else is rejected at the boundary.
SUPPORTED_DTYPES: tuple[np.dtype, ...] = tuple(
    np.dtype(t) for t in ("uint8", "uint16", "int16", "float32", "float64")
)

NonFinitePolicy = Literal["raise", "replace"]

#: voxels from which :attr:`Volume.value_range` comes from the threaded brick pass
#: (below it, NumPy's serial min and max cost less than starting threads)
_RANGE_FROM_BRICKS = 1 << 24
#: Brick edge whose statistics are computed from voxels; coarser multiples of it
#: (macrocells of 16 or 32) are reduced from these.
BASE_BRICK = 8


@dataclass(frozen=True)
class BrickStats:
    """Per-brick value ranges of a volume (computed once, reused by every TF).

    Attributes
    ----------
    brick_size : int
        Cells per brick edge ``B``; brick ``b`` spans voxels ``[b*B, (b+1)*B]``.
    vmin, vmax : ndarray of float64, shape (nbz, nby, nbx)
        Value range of each brick including a one-voxel apron, so any trilinear
        sample (and any central-difference neighbour) inside the brick lies in
        ``[vmin, vmax]``.
    build_ms : float
        Wall time of the computation (first-use kernel compilation excluded).
    compile_ms : float
        First-use compilation (or cache load) of the brick kernel for this dtype
        in this process, done on a tiny array before the timed pass; 0 after that.
    """

    brick_size: int
    vmin: np.ndarray
    vmax: np.ndarray
    build_ms: float
    compile_ms: float = 0.0

    @property
    def shape(self) -> tuple[int, int, int]:
        """Brick counts ``(nbz, nby, nbx)``."""
        return self.vmin.shape  # type: ignore[return-value]

    @property
    def nbytes(self) -> int:
        return int(self.vmin.nbytes + self.vmax.nbytes)


@dataclass(frozen=True)
class BrickLabels:
    """Per-brick sets of the label ids a volume holds (computed once, reused by every label TF).

    Attributes
    ----------
    brick_size : int
        Cells per brick edge ``B`` (bricks as in :class:`BrickStats`, apron included).
    ids : (n_ids,) int64
        The distinct ids in the volume, ascending; an id's *rank* is its position here.
    words : (nbz, nby, nbx, n_words) uint64
        Bit ``r % 64`` of word ``r // 64`` is set when the id of rank ``r`` occurs in
        the brick or its one-voxel apron.
    build_ms : float
        Wall time of the computation.
    """

    brick_size: int
    ids: np.ndarray
    words: np.ndarray
    build_ms: float

    def rank_words(self, visible) -> np.ndarray:
        """The ids in ``visible`` that the volume holds, as a rank bit set ``(n_words,)`` uint64."""
        out = np.zeros(self.words.shape[-1], np.uint64)
        v = np.asarray(list(visible), np.int64)
        r = np.searchsorted(self.ids, v)
        present = (r < len(self.ids)) & (self.ids[np.minimum(r, len(self.ids) - 1)] == v)
        for rank in r[present]:
            out[rank >> 6] |= np.uint64(1) << np.uint64(rank & 63)
        return out


#: most distinct ids :meth:`Volume.brick_labels` tracks (64 words a brick); a volume
#: with more is no segmentation, and its label TFs classify bricks by range only
MAX_BRICK_LABELS = 4096
#: largest id span (max id - min id) tracked: the id -> rank table is int32
_MAX_ID_SPAN = 1 << 20
_MISSING = object()  # Volume.derived's "no entry" (an entry may be any object)


class Volume:
    """A scalar volume: voxel array, spacing and origin.

    Parameters
    ----------
    data : array_like, shape (nz, ny, nx)
        Voxel values, C-ordered ``[k, j, i]``. dtype must be one of uint8, uint16,
        int16, float32 or float64 (see :data:`SUPPORTED_DTYPES`); bool and other
        integer types are converted when lossless, otherwise rejected.
    spacing : float or sequence of 3 floats, optional
        Voxel size along ``(x, y, z)`` in world units. Default 1.
    origin : sequence of 3 floats, optional
        World position of voxel ``(0, 0, 0)``. Default 0.
    name : str, optional
        Label used in messages and benchmark records.
    nonfinite : {"raise", "replace"}, optional
        What to do with NaN/Inf in float data: ``"raise"`` (default) rejects the
        volume; ``"replace"`` substitutes the finite minimum for NaN and -Inf and the
        finite maximum for +Inf.
    orientation : str or sequence of 3 str, optional
        Anatomical axis codes of ``+i, +j, +k`` (``"RAS"``, ``("L", "P", "S")``): where
        each voxel axis points in the patient. Default None (not anatomical, or not
        known); the readers fill it from NRRD ``space`` and NIfTI sform/qform. Named
        views (``Camera.orbit(vol, view="anterior")``) need it.

    Attributes
    ----------
    orientation : tuple of 3 str or None
        The axis codes, upper case.

    Raises
    ------
    VolumeDataError
        Wrong number of dimensions, zero-size axis, unsupported dtype or NaN/Inf.
    ParameterError
        Spacing or origin not one or three finite numbers (spacing > 0), an unknown
        ``nonfinite`` policy, or orientation not three axis codes (one of L/R, A/P, S/I).

    Examples
    --------
    >>> import numpy as np, sparsecast as sc
    >>> vol = sc.Volume(np.zeros((4, 5, 6), np.float32), spacing=(1, 1, 2))
    >>> vol.dims
    (6, 5, 4)
    """

    #: how a file-backed volume's voxels can be opened again elsewhere (an
    #: :class:`~sparsecast.io.sources.SourceRecipe` that :func:`~sparsecast.io.load_volume`
    #: sets for memory-mapped and lazy files); None for voxels that live only here
    source_recipe = None

    def __init__(
        self,
        data,
        spacing=1.0,
        origin=0.0,
        *,
        name: str = "volume",
        nonfinite: NonFinitePolicy = "raise",
        orientation: str | Orientation | None = None,
    ) -> None:
        one_of(nonfinite, "nonfinite", ("raise", "replace"), expected="'raise' or 'replace'")
        arr = np.asarray(data)
        check_voxel_shape(arr.shape, name)
        arr = _coerce_dtype(arr, name)
        value_range = None
        if arr.dtype.kind == "f":
            arr, value_range = _check_finite(arr, name, nonfinite)
        # A read-only *view*: cached brick statistics and indices must stay valid,
        # but the caller's own array keeps its flags (no copy when contiguous).
        self._data = np.ascontiguousarray(arr).view()
        self._data.flags.writeable = False
        self.spacing = vector3(spacing, "spacing", positive=True)
        self.origin = vector3(origin, "origin")
        self.name = name
        self.orientation: Orientation | None = check_orientation(orientation)
        self._range: tuple[float, float] | None = value_range
        self._bricks: dict[int, BrickStats] = {}
        self._labels: dict[int, BrickLabels | None] = {}
        self._ids: tuple[np.ndarray, np.ndarray] | None | bool = False  # False: not computed yet
        self._derived: dict[Hashable, Any] = {}  # see derived()

    # -- basic properties -------------------------------------------------
    @property
    def data(self) -> np.ndarray:
        """Read-only voxel array, shape ``(nz, ny, nx)``."""
        return self._data

    def voxels(self, tf=None, *, mode: str = "dvr") -> np.ndarray:
        """The voxels as the kernels read them: here the dense ``(nz, ny, nx)`` array.

        A :class:`~sparsecast.storage.BrickedVolume` returns its page table and pool
        instead, with every brick ``tf`` can see made resident first; renderers and
        index builds call this rather than reading :attr:`data`.
        """
        return self._data

    def histogram(self, bins: int = 64) -> tuple[np.ndarray, np.ndarray]:
        """``(counts, edges)`` of the voxel values over :attr:`value_range` (from at most
        about 4 M voxels, evenly strided: an overview for tools, not a statistic)."""
        lo, hi = self.value_range
        if not hi > lo:
            hi = lo + 1.0
        flat = self._data.reshape(-1)
        counts, edges = np.histogram(flat[:: max(1, flat.size // 4_000_000)], bins=bins, range=(lo, hi))
        return counts.astype(np.int64), edges

    @property
    def shape(self) -> tuple[int, int, int]:
        """Array shape ``(nz, ny, nx)``."""
        return self._data.shape  # type: ignore[return-value]

    @property
    def dims(self) -> tuple[int, int, int]:
        """Voxel counts ``(nx, ny, nz)``."""
        nz, ny, nx = self._data.shape
        return (nx, ny, nz)

    @property
    def dtype(self) -> np.dtype:
        return self._data.dtype

    @property
    def nbytes(self) -> int:
        return int(self._data.nbytes)

    @property
    def value_range(self) -> tuple[float, float]:
        """``(min, max)`` of the voxel values (cached)."""
        if self._range is None:
            if self._data.size >= _RANGE_FROM_BRICKS:
                # The brick pass reads every voxel once on every core, and its windows
                # cover every voxel: its range is the value range, and the brick
                # statistics every index needs come with it.
                bricks = self.brick_stats(BASE_BRICK)
                self._range = (float(bricks.vmin.min()), float(bricks.vmax.max()))
            else:
                self._range = (float(self._data.min()), float(self._data.max()))
        return self._range

    @property
    def extent(self) -> np.ndarray:
        """Index-space size of the domain, ``(nx-1, ny-1, nz-1)``."""
        return np.array(self.dims, dtype=np.float64) - 1.0

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World-space bounding box ``(lower, upper)`` corners (x, y, z)."""
        lo = self.origin.copy()
        hi = self.origin + self.spacing * self.extent
        return lo, hi

    @property
    def center(self) -> np.ndarray:
        lo, hi = self.bounds
        return 0.5 * (lo + hi)

    @property
    def diagonal(self) -> float:
        """World-space length of the domain's diagonal."""
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    def require_renderable(self) -> None:
        """Refuse a volume the ray caster cannot show: fewer than 2 voxels along an axis.

        Voxels are lattice points and the rendered domain is the box between the
        first and last voxel centres, so an axis of one voxel gives a box of zero
        thickness that every ray crosses without taking a sample: the image would be
        empty from every view. Raising says so instead of returning a blank image.

        Raises
        ------
        VolumeDataError
            Naming the shape and the axis.
        """
        thin = [axis for axis, n in zip("xyz", self.dims) if n < 2]
        if thin:
            raise VolumeDataError(
                f"{self.name}: shape (nz, ny, nx) = {self.shape} has a single voxel along "
                f"{', '.join(thin)}; rendering needs at least 2 voxels per axis (the volume is the box "
                f"between voxel centres, of zero thickness here); stack or pad the slice"
            )

    def __repr__(self) -> str:
        nx, ny, nz = self.dims
        return (
            f"Volume(name={self.name!r}, dims={nx}x{ny}x{nz}, dtype={self.dtype}, "
            f"spacing={tuple(self.spacing.tolist())}, origin={tuple(self.origin.tolist())}"
            + (f", orientation={''.join(self.orientation)!r})" if self.orientation else ")")
        )

    # -- per-volume precomputation ----------------------------------------
    def derived(self, key: Hashable) -> Any | None:
        """What :meth:`keep_derived` stored under ``key``, or None.

        A store for what renderers compute from this volume and reuse across frames
        (e.g. the index :func:`sparsecast.render` builds from a name). It lives and
        dies with the volume, and the voxels are read-only, so nothing in it goes
        stale with them; what else an entry depends on (a TF) is its owner's to check.
        A hit makes the entry the most recently used (the last to be dropped).
        """
        value = self._derived.pop(key, _MISSING)
        if value is _MISSING:
            return None
        # Least recently used goes first: an index read at every frame outlives the
        # ones a TF drag stores beside it (each emptiness keeps its own, render.reuse).
        self._derived[key] = value
        return value

    def keep_derived(self, key: Hashable, value: Any, limit: int = 4) -> None:
        """Store ``value`` under ``key`` (see :meth:`derived`), dropping the least
        recently used entries beyond ``limit``, so the store never grows past a few."""
        self._derived.pop(key, None)
        self._derived[key] = value
        while len(self._derived) > max(1, int(limit)):
            del self._derived[next(iter(self._derived))]

    def brick_stats(self, brick_size: int = 8) -> BrickStats:
        """Per-brick min/max with a one-voxel apron (computed once, then cached).

        Parameters
        ----------
        brick_size : int, optional
            Cells per brick edge (default 8).
        """
        brick_size = as_int(brick_size, "brick_size", lo=1)
        cached = self._bricks.get(brick_size)
        if cached is not None:
            return cached
        nbz, nby, nbx = (max(1, -(-(n - 1) // brick_size)) for n in self.shape)
        t0 = time.perf_counter()
        compile_ms = 0.0
        base = BASE_BRICK
        # (Only for bricks no larger than the volume: the padding of a bigger
        # factor would allocate far more than the data, e.g. --brick-size 1000000.)
        if brick_size > base and brick_size % base == 0 and brick_size <= max(self.shape):
            # A coarse brick's apron range is exactly the union of the apron
            # ranges of the base bricks it covers, so reduce those: no voxel pass.
            fine = self.brick_stats(base)
            vmin = _block_reduce(fine.vmin, brick_size // base, np.minimum, (nbz, nby, nbx))
            vmax = _block_reduce(fine.vmax, brick_size // base, np.maximum, (nbz, nby, nbx))
        else:
            compile_ms = _warm_brick_kernel(self._data.dtype)
            t0 = time.perf_counter()
            vmin = np.empty((nbz, nby, nbx), np.float64)
            vmax = np.empty((nbz, nby, nbx), np.float64)
            brick_ranges(self._data, brick_size, vmin, vmax)
        ms = (time.perf_counter() - t0) * 1e3
        stats = BrickStats(brick_size, vmin, vmax, ms, compile_ms)
        self._bricks[brick_size] = stats
        return stats


    def brick_labels(self, brick_size: int = 8) -> BrickLabels | None:
        """Per-brick label-id sets with a one-voxel apron (computed once, then cached).

        ``None`` when the voxels are not integral ids or hold more than
        :data:`MAX_BRICK_LABELS` distinct values (then label TFs classify by range).

        Parameters
        ----------
        brick_size : int, optional
            Cells per brick edge (default 8).
        """
        brick_size = as_int(brick_size, "brick_size", lo=1)
        if brick_size in self._labels:
            return self._labels[brick_size]
        t0 = time.perf_counter()
        result = None
        ids = self.label_ids()
        if ids is not None:
            nbz, nby, nbx = (max(1, -(-(n - 1) // brick_size)) for n in self.shape)
            n_words = (len(ids) - 1) // 64 + 1
            words = np.zeros((nbz, nby, nbx, n_words), np.uint64)
            if brick_size > BASE_BRICK and brick_size % BASE_BRICK == 0 and brick_size <= max(self.shape):
                # A coarse brick's set is the union of the base bricks' sets it covers
                # (only then are the base sets worth computing: no pass for bricks of 4).
                f = brick_size // BASE_BRICK
                fine = self.brick_labels(BASE_BRICK).words
                pad = [(0, s * f - n) for s, n in zip((nbz, nby, nbx), fine.shape[:3])] + [(0, 0)]
                fine = np.pad(fine, pad).reshape(nbz, f, nby, f, nbx, f, n_words)
                words = np.bitwise_or.reduce(np.bitwise_or.reduce(np.bitwise_or.reduce(fine, axis=5), axis=3), axis=1)
            else:
                lo = int(ids[0])
                rank_of = np.zeros(int(ids[-1]) - lo + 1, np.int32)
                rank_of[ids - lo] = np.arange(len(ids), dtype=np.int32)
                with parallel_section():
                    brick_label_words(self._data, lo, rank_of, brick_size, nbz, nby, nbx, words)
            result = BrickLabels(brick_size, ids, words, (time.perf_counter() - t0) * 1e3)
        self._labels[brick_size] = result
        return result

    def label_ids(self) -> np.ndarray | None:
        """The distinct voxel values, ascending (int64), when the volume can be a label
        volume: integral values spanning less than 2^20 with at most
        :data:`MAX_BRICK_LABELS` distinct ones; else None."""
        counts = self.label_counts()
        return None if counts is None else counts[0]

    def label_counts(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(ids, voxel counts)`` of a label volume (see :meth:`label_ids`), else None
        (computed once, one pass over the voxels)."""
        if self._ids is False:
            d = self._data
            lo, hi = self.value_range
            found = None
            # Ids must be integers of a span a lookup table of at most 4 MiB covers.
            if hi - lo < _MAX_ID_SPAN and (d.dtype.kind in "ui" or _integral(d)):
                counts = np.zeros(int(hi) - int(lo) + 1, np.int64)
                count_values(d, int(lo), counts)
                ids = np.flatnonzero(counts)
                if len(ids) <= MAX_BRICK_LABELS:
                    found = (ids + int(lo), counts[ids])
            self._ids = found
        return self._ids  # type: ignore[return-value]


def _integral(d: np.ndarray) -> bool:
    """Whether every value of a float array is an integer (chunked: no full-size temporary)."""
    flat = d.reshape(-1)
    step = 1 << 22
    return all(np.array_equal(c, np.floor(c)) for c in (flat[i:i + step] for i in range(0, flat.size, step)))


_WARM_DTYPES: set[str] = set()


def _tiny_voxels(dtype: np.dtype) -> np.ndarray:
    """3^3 voxels typed as a Volume's: read-only, which Numba types apart from writable
    (a writable warm-up array compiled a specialisation the real pass never used)."""
    tiny = np.zeros((3, 3, 3), dtype)
    tiny.setflags(write=False)
    return tiny


def _warm_brick_kernel(dtype: np.dtype) -> float:
    """Compile (or load) the kernels of :func:`brick_ranges` for ``dtype`` and a Volume's
    read-only voxels on 3^3 arrays, once per process.

    Returns the milliseconds spent (0 when warm): the first ``sparsecast info`` used
    to report seconds of compilation as the brick statistics' time.
    """
    if dtype.str in _WARM_DTYPES:
        return 0.0
    t0 = time.perf_counter()
    warm_brick_ranges(_tiny_voxels(dtype))
    _WARM_DTYPES.add(dtype.str)
    return (time.perf_counter() - t0) * 1e3


def _block_reduce(a: np.ndarray, f: int, op, shape: tuple[int, int, int]) -> np.ndarray:
    """Reduce ``f x f x f`` blocks of ``a`` with ``op`` (partial blocks at the far ends)."""
    pad = [(0, s * f - n) for s, n in zip(shape, a.shape)]
    fill = np.inf if op is np.minimum else -np.inf
    a = np.pad(a, pad, constant_values=fill)
    nz, ny, nx = shape
    return op.reduce(op.reduce(op.reduce(a.reshape(nz, f, ny, f, nx, f), axis=5), axis=3), axis=1)


def _coerce_dtype(arr: np.ndarray, name: str) -> np.ndarray:
    if arr.dtype in SUPPORTED_DTYPES:
        return arr
    supported = ", ".join(str(d) for d in SUPPORTED_DTYPES)
    if arr.dtype == np.bool_:
        return arr.astype(np.uint8)
    if arr.dtype.kind in "iu" and arr.size:
        # Convert other integer types only where no value changes.
        lo, hi = int(arr.min()), int(arr.max())
        for target in ("uint8", "int16", "uint16"):
            info = np.iinfo(target)
            if info.min <= lo and hi <= info.max:
                return arr.astype(target)
        return arr.astype(np.float64) if arr.dtype.itemsize <= 4 else _reject(arr, name, supported)
    if arr.dtype == np.float16:
        return arr.astype(np.float32)
    return _reject(arr, name, supported)


def _reject(arr: np.ndarray, name: str, supported: str) -> np.ndarray:
    raise VolumeDataError(f"{name!r}: unsupported dtype {arr.dtype}; expected one of {supported}")


def check_voxel_shape(shape: tuple[int, ...], name: str) -> tuple[int, int, int]:
    """``shape`` as ``(nz, ny, nx)``, or the data error every kind of volume raises (in
    memory, bricked, scanned chunk by chunk) for a shape that is not 3-D or has a
    zero-size axis, naming the volume ``name``."""
    shape = tuple(int(n) for n in shape)
    if len(shape) != 3:
        raise VolumeDataError(f"{name!r}: expected a 3-D array of shape (nz, ny, nx), got {len(shape)}-D shape {shape}")
    if min(shape) == 0:
        raise VolumeDataError(f"{name!r}: volume has a zero-size axis, shape {shape}")
    return shape


def nonfinite_error(name: str, n_bad: int, every: bool = False) -> VolumeDataError:
    """The data error for ``n_bad`` NaN or Inf voxels of volume ``name`` under the policy
    ``nonfinite="raise"``, or (``every``) for a volume with no finite voxel at all, which
    ``"replace"`` cannot mend (the one wording of the in-memory and the scanned paths)."""
    if every:
        return VolumeDataError(f"{name!r}: every voxel is NaN or Inf; nothing to replace them with")
    return VolumeDataError(
        f"{name!r}: {n_bad} voxel(s) are NaN or Inf; expected finite values "
        f"(pass nonfinite='replace', on the command line --nonfinite replace, to substitute the finite "
        f"min/max)"
    )


def _check_finite(arr: np.ndarray, name: str, policy: str) -> tuple[np.ndarray, tuple[float, float] | None]:
    """``(voxels, value range or None)`` after the NaN/Inf policy."""
    # NaN propagates through min and max and Inf is its own extreme, so two reductions
    # with no temporary find out (a full-size bool mask took 1/4 of float32 data).
    lo, hi = arr.min(), arr.max()
    if np.isfinite(lo) and np.isfinite(hi):
        return arr, (float(lo), float(hi))
    finite = np.isfinite(arr)
    n_bad = int(arr.size - np.count_nonzero(finite))
    if policy == "raise":
        raise nonfinite_error(name, n_bad)
    if not finite.any():
        raise nonfinite_error(name, n_bad, every=True)
    lo = arr[finite].min()
    hi = arr[finite].max()
    return np.nan_to_num(arr, nan=lo, posinf=hi, neginf=lo), None
