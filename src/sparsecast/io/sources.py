"""Lazy volume sources: arrays on disk that are read a region at a time, never whole.

:func:`open_source` opens

* a **Zarr** v2 or v3 array, or a group holding a single 3-D array,
* an **OME-Zarr** multiscale image (its metadata read with the ``ome-zarr`` package;
  one level picked by index or path, the finest by default; axes ``t``/``c`` of size 1
  dropped; spacing and origin from the coordinate transformations),
* an **HDF5** dataset, ``file.h5:/path/to/dataset`` (h5py; the path may be left out
  when the file holds a single 3-D dataset),
* a NumPy ``.npy`` file (``np.load(mmap_mode="r")``), and
* raw files and raw-encoded NRRD (``np.memmap``; the layout from the headers as
  :mod:`.raw` and :mod:`.nrrd` parse them; gzip/bzip2 NRRD cannot be mapped),

and returns a :class:`Source`: the array-like (``shape`` ``(nz, ny, nx)``, ``dtype``,
basic slicing that returns native-endian ndarrays), spacing and origin ``(x, y, z)``
and what the store is. Everything is opened read-only; nothing is ever written into
a source.

Missing and corrupt chunks
--------------------------
A Zarr chunk that is absent from the store reads as the fill value in ``zarr``: that
is the format's meaning, and stores written with ``write_empty_chunks=False`` (zarr's
default) leave every empty chunk of a sparse volume out. But a volume whose chunk file
was lost would then render a hole without a word. ``missing_chunks="auto"`` (default)
tells the two apart by who wrote the store: ``sparsecast convert`` writes every chunk
and marks the store complete (``attrs["sparsecast"]["complete"]``), so there an absent
chunk raises, naming the chunk and the store; elsewhere it reads as the fill value.
``"raise"`` and ``"fill"`` force either. A chunk that fails to decode is found by
reading the touched chunks one by one, and named.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path
from typing import Any, Literal

import numpy as np

from .._util.checks import fail, one_of
from ..errors import FileFormatError, ParameterError, SparsecastError
from .files import require_regular_file
from .names import stem_of, suffix_of
from .nrrd import raw_payload
from .raw import raw_layout

__all__ = ["Source", "SourceRecipe", "Level", "SourceKind", "open_source", "time_steps", "split_hdf5_path", "is_lazy_path", "is_zarr_dir",
           "SOURCE_ATTRS"]

SourceKind = Literal["zarr", "ome-zarr", "hdf5", "npy", "raw", "nrrd"]
#: the attribute of a plain Zarr array holding spacing and origin (x, y, z), as
#: :func:`sparsecast.io.convert.convert_volume` writes them
SOURCE_ATTRS = "sparsecast"
_HDF5_RE = re.compile(r"^(?P<file>.*?\.(?:h5|hdf5|hdf|he5))(?::(?P<dataset>.*))?$", re.IGNORECASE | re.DOTALL)
_RAW_SUFFIXES = (".raw", ".bin", ".dat")


@dataclass(frozen=True)
class Level:
    """One resolution level of a source.

    Attributes
    ----------
    name : str
        The level's path in the store (OME-Zarr ``datasets[i].path``), or the source's
        name for a single-resolution source.
    shape : (nz, ny, nx)
    spacing, origin : ndarray of float64, shape (3,)
        Voxel size and world position of voxel (0, 0, 0), ``(x, y, z)``.
    """

    name: str
    shape: tuple[int, int, int]
    spacing: np.ndarray
    origin: np.ndarray


@dataclass(frozen=True)
class Source:
    """A volume on disk, read a region at a time.

    Attributes
    ----------
    array : array-like
        ``shape`` ``(nz, ny, nx)``, ``dtype`` (native byte order), ``ndim``, and
        NumPy basic slicing (integers, slices, Ellipsis) returning ndarrays.
    spacing, origin : ndarray of float64, shape (3,)
        ``(x, y, z)``; 1 and 0 where the store holds none.
    name : str
        Label for messages (the file stem).
    path : Path
        The file or store.
    kind : {"zarr", "ome-zarr", "hdf5", "npy", "raw", "nrrd"}
    chunks : (cz, cy, cx) or None
        The store's chunk (Zarr: shard, if sharded) shape; None for contiguous data.
    levels : tuple of Level
        Resolution levels, finest first (one for a single-resolution source).
    level : str
        The name of the level ``array`` reads.
    steps : int
        Time steps in the store (Zarr with ``time=``); ``array`` reads one.
    orientation : tuple of 3 str or None
        Anatomical axis codes (raw NRRD ``space``), else None.
    """

    array: Any
    spacing: np.ndarray
    origin: np.ndarray
    name: str
    path: Path
    kind: SourceKind
    chunks: tuple[int, int, int] | None
    levels: tuple[Level, ...]
    level: str
    orientation: tuple[str, str, str] | None = None
    _keep: Any = field(default=None, repr=False, compare=False)  # an open file the array reads
    #: time steps of the store (``array`` reads the one ``time=`` chose); 1 without a t axis
    steps: int = 1

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(self.array.shape)  # type: ignore[return-value]

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(self.array.dtype)

    @property
    def nbytes(self) -> int:
        """Bytes of the voxels once decoded (the dense size)."""
        return int(math.prod(self.shape) * self.dtype.itemsize)


# -- the array-likes --------------------------------------------------------------

def _basic_key(key, shape: tuple[int, ...], where: str) -> tuple:
    """``key`` as a tuple of one int or slice per axis (Ellipsis expanded), basic indexing only."""
    key = key if isinstance(key, tuple) else (key,)
    if sum(k is Ellipsis for k in key) > 1:
        raise ParameterError(f"{where}: an index can only have a single Ellipsis, got {key!r}")
    if Ellipsis in key:
        i = key.index(Ellipsis)
        key = key[:i] + (slice(None),) * (len(shape) - len(key) + 1) + key[i + 1:]
    if len(key) > len(shape):
        raise ParameterError(f"{where}: too many indices ({len(key)}) for a {len(shape)}-D array")
    key = key + (slice(None),) * (len(shape) - len(key))
    for k, n in zip(key, shape):
        if isinstance(k, (int, np.integer)) and not isinstance(k, bool):
            if not -n <= int(k) < n:
                raise ParameterError(f"{where}: index {int(k)} is out of bounds for an axis of size {n}")
        elif not isinstance(k, slice):
            raise ParameterError(
                f"{where}: expected basic indexing (integers, slices, Ellipsis), got {type(k).__name__} {k!r}"
            )
    return tuple(int(k) if not isinstance(k, slice) else k for k in key)


def _axis_chunks(k, n: int, c: int) -> np.ndarray:
    """Chunk indices along one axis of chunk size ``c`` that index ``k`` touches."""
    if isinstance(k, int):
        return np.array([(k % n) // c])
    idx = np.arange(*k.indices(n))
    return np.unique(idx // c)


def _scalar(value):
    """A NumPy scalar as the Python number it holds (``0``, not ``np.uint8(0)``), for messages."""
    return value.item() if isinstance(value, np.generic) else value


def _native(arr) -> np.ndarray:
    arr = np.asarray(arr)
    if arr.dtype.byteorder not in ("=", "|"):
        native = arr.dtype.newbyteorder("=")
        # "<i2" on a little-endian machine is native: a view, not a copy of the region
        arr = arr.view(native) if arr.dtype == native else arr.astype(native)
    return arr


class _Voxels:
    """Read-only array-like over a store's array: basic slicing, errors that name the chunk.

    Subclasses give ``_array`` (the library's array), ``_prefix`` (indices of leading
    size-1 axes dropped), ``_grid`` (the chunk shape of all axes, or None),
    ``_where`` (the store, for messages) and ``_chunk_name(coords)``.
    """

    _array: Any
    _prefix: tuple[int, ...] = ()
    _grid: tuple[int, ...] | None = None
    _where: str = ""

    ndim = 3

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(int(n) for n in self._array.shape[len(self._prefix):])  # type: ignore[return-value]

    @property
    def dtype(self) -> np.dtype:
        dt = np.dtype(self._array.dtype)
        return dt.newbyteorder("=") if dt.byteorder not in ("=", "|") else dt

    @property
    def nbytes(self) -> int:
        return int(math.prod(self.shape) * self.dtype.itemsize)

    def __len__(self) -> int:
        return self.shape[0]

    def __array__(self, dtype=None, copy=None):
        arr = self[...]
        return arr if dtype is None else arr.astype(dtype)

    def _chunk_name(self, coords: tuple[int, ...]) -> str:
        return f"chunk {coords}"

    def _check(self, full: tuple, chunks: list[tuple[int, ...]]) -> None:
        """Raise for a chunk that must exist and does not (subclasses that can tell)."""

    def _touched(self, full: tuple) -> list[tuple[int, ...]]:
        shape = tuple(self._array.shape)
        per_axis = [_axis_chunks(k, n, c) for k, n, c in zip(full, shape, self._grid)]
        return [tuple(int(i) for i in t) for t in product(*per_axis)]

    def __getitem__(self, key) -> np.ndarray:
        key = _basic_key(key, self.shape, self._where)
        full = self._prefix + key
        chunks = self._touched(full) if self._grid is not None else []
        self._check(full, chunks)
        try:
            return _native(self._array[full])
        except (SparsecastError, MemoryError):
            raise  # out of memory is no fault of the store's
        except Exception as exc:  # noqa: BLE001 - boundary: name the chunk that fails
            raise self._read_failure(full, chunks, exc) from exc

    def _read_failure(self, full: tuple, chunks: list[tuple[int, ...]], exc: Exception) -> FileFormatError:
        """Read the touched chunks one at a time to find the one that fails, and name it."""
        for coords in chunks:
            region = tuple(slice(i * c, (i + 1) * c) for i, c in zip(coords, self._grid))
            try:
                self._array[region]
            except Exception as chunk_exc:  # noqa: BLE001
                return FileFormatError(
                    f"{self._where}: {self._chunk_name(coords)} cannot be read: {type(chunk_exc).__name__}: "
                    f"{chunk_exc or 'no detail'} (chunk corrupt or truncated)"
                )
        return FileFormatError(
            f"{self._where}: cannot read region {full!r}: {type(exc).__name__}: {exc or 'no detail'} "
            f"(store corrupt or truncated)"
        )


class ZarrVoxels(_Voxels):
    """A zarr array (v2 or v3; sharded or not) as a :class:`Source` array."""

    def __init__(self, array, prefix: tuple[int, ...], where: str, missing_chunks: str) -> None:
        self._array = array
        self._prefix = prefix
        self._where = where
        self._missing = missing_chunks
        self._grid = tuple(int(c) for c in (array.shards or array.chunks))
        store = array.store
        root = getattr(store, "root", None)  # a LocalStore: chunk files can be looked up
        self._root = Path(root) / array.path if root is not None else None

    @property
    def chunks(self) -> tuple[int, int, int]:
        return self._grid[len(self._prefix):]  # type: ignore[return-value]

    def _key(self, coords: tuple[int, ...]) -> str:
        return self._array.metadata.encode_chunk_key(coords)

    def _chunk_name(self, coords: tuple[int, ...]) -> str:
        return f"chunk {self._key(coords)!r} (chunk index {coords[len(self._prefix):]})"

    def _check(self, full: tuple, chunks: list[tuple[int, ...]]) -> None:
        if self._missing == "fill" or self._root is None:
            return
        for coords in chunks:
            if not (self._root / self._key(coords)).is_file():
                raise FileFormatError(
                    f"{self._where}: {self._chunk_name(coords)} is missing from the store; expected every "
                    f"chunk of a complete store (pass missing_chunks='fill' to read absent chunks as the "
                    f"fill value {_scalar(self._array.fill_value)!r}: stores written with write_empty_chunks=False "
                    f"leave empty chunks out)"
                )


class H5Voxels(_Voxels):
    """An h5py dataset as a :class:`Source` array (the file stays open while it lives)."""

    def __init__(self, dataset, where: str) -> None:
        self._array = dataset
        self._where = where
        self._grid = tuple(int(c) for c in dataset.chunks) if dataset.chunks else None

    @property
    def chunks(self):
        return self._grid

    def _chunk_name(self, coords: tuple[int, ...]) -> str:
        return (f"chunk at voxel {tuple(i * c for i, c in zip(coords, self._grid))} "
                f"(chunk index {coords}) of dataset {self._array.name!r}")


class MemmapVoxels(_Voxels):
    """A memory map (``.npy``, raw, raw NRRD) as a :class:`Source` array."""

    def __init__(self, mm: np.ndarray, where: str) -> None:
        self._array = mm
        self._where = where

    @property
    def chunks(self):
        return None


# -- opening ----------------------------------------------------------------------

def split_hdf5_path(path: str | os.PathLike) -> tuple[Path, str | None] | None:
    """``("file.h5", "/path/to/dataset")`` for ``file.h5:/path/to/dataset`` (dataset None
    when no ``:`` follows), or None for a path that names no HDF5 file."""
    m = _HDF5_RE.match(os.fspath(path))
    if m is None:
        return None
    return Path(m.group("file")), m.group("dataset")


def is_zarr_dir(p: Path) -> bool:
    """Whether ``p`` is a Zarr store: a directory with v3 or v2 metadata."""
    return p.is_dir() and any((p / n).is_file() for n in ("zarr.json", ".zarray", ".zgroup"))


def is_lazy_path(path: str | os.PathLike) -> bool:
    """Whether :func:`open_source` can open ``path`` without reading it whole (by its name:
    a Zarr store, an HDF5 file, ``.npy``, raw, ``.nrrd``/``.nhdr``; a gzip NRRD is only
    found out on opening)."""
    if split_hdf5_path(path) is not None:
        return True
    p = Path(path)
    return is_zarr_dir(p) or suffix_of(p) in (".npy", ".nrrd", ".nhdr", ".zarr") + _RAW_SUFFIXES


@dataclass(frozen=True)
class SourceRecipe:
    """How to open a source again, elsewhere: what a cluster worker needs to read its
    piece of a file itself instead of receiving the voxels (the path must be readable
    there, e.g. on a shared file system).

    Attributes
    ----------
    path : str
        As given to :func:`open_source`.
    options : dict
        Its keyword arguments (level, missing_chunks, raw layout, allow_outside).
    """

    path: str
    options: dict

    def open(self) -> Source:
        """:func:`open_source` with the recorded arguments."""
        return open_source(self.path, **self.options)


def open_source(
    path: str | os.PathLike,
    *,
    level: int | str | None = None,
    missing_chunks: Literal["auto", "raise", "fill"] = "auto",
    dims: tuple[int, int, int] | None = None,
    dtype: str | np.dtype | None = None,
    byte_order: Literal["little", "big"] = "little",
    header_offset: int = 0,
    allow_outside: bool = False,
    time: int | None = None,
) -> Source:
    """Open a volume on disk lazily: nothing but headers and metadata is read.

    Parameters
    ----------
    path : str or PathLike
        A Zarr store (``.zarr`` directory: an array, a group with one 3-D array, or an
        OME-Zarr image), ``file.h5:/dataset`` (or ``file.h5`` with a single 3-D
        dataset), ``.npy``, ``.raw``/``.bin``/``.dat`` or a raw-encoded ``.nrrd``/``.nhdr``.
    level : int or str, optional
        OME-Zarr: the level, by index into ``levels`` or by its path (``"2"``).
        Default: the finest (level 0).
    missing_chunks : {"auto", "raise", "fill"}, optional
        Zarr: an absent chunk raises, or reads as the fill value; ``"auto"`` (default)
        raises in stores ``sparsecast convert`` wrote (complete by construction) and
        fills elsewhere (see the module docstring).
    dims, dtype, byte_order, header_offset : optional
        Raw files: the layout, as :func:`~.volumes.load_volume` takes it.
    allow_outside : bool, optional
        NRRD: follow a detached header's data file outside its folder.
    time : int, optional
        Zarr: the step of a time series stored as a 4-D ``(t, nz, ny, nx)`` array (or a
        group holding one), or of an OME-Zarr image with a ``t`` axis. Default: the
        store holds a single 3-D volume (a ``t`` axis of size 1 is fine).

    Returns
    -------
    Source

    Raises
    ------
    FileFormatError
        Missing or unreadable file or store, not a 3-D scalar volume, a group with no
        or several 3-D arrays (listing them), an HDF5 path that names no dataset
        (listing the datasets), a gzip/bzip2 NRRD (cannot be mapped), a non-numeric
        dtype, a size that does not match the header.
    ParameterError
        An OME-Zarr level that does not exist (listing the levels), ``level`` for a
        single-resolution source, raw options for a non-raw source, axes t/c of size > 1.
    """
    one_of(missing_chunks, "missing_chunks", ("auto", "raise", "fill"), expected="'auto', 'raise' or 'fill'")
    if isinstance(path, os.PathLike):
        path = os.fspath(path)
    if not isinstance(path, str) or not path or "\x00" in path:
        raise fail("path", "a non-empty file path", path)
    h5 = split_hdf5_path(path)
    p = Path(path)
    raw_opts = [n for n, v in (("dims", dims), ("dtype", dtype)) if v is not None]
    if header_offset:
        raw_opts.append("header_offset")
    is_raw = h5 is None and suffix_of(p) in _RAW_SUFFIXES
    if raw_opts and not is_raw:
        verb = "applies" if len(raw_opts) == 1 else "apply"
        raise ParameterError(f"{', '.join(raw_opts)}: {verb} only to raw files (.raw/.bin/.dat), not {path!r}")
    if level is not None and (h5 is not None or not p.is_dir()):
        raise ParameterError(f"level: {path!r} has a single resolution level; level= applies to OME-Zarr images")
    if h5 is not None:
        return _open_hdf5(*h5)
    if p.is_dir() or suffix_of(p) == ".zarr":
        return _open_zarr(p, level, missing_chunks, time)
    if time is not None:
        raise ParameterError(f"time: {path!r} holds one volume; time= applies to Zarr stores with a time axis")
    suffix = suffix_of(p)
    if suffix == ".npy":
        return _open_npy(p)
    if is_raw:
        require_regular_file(p, "raw volume file")
        shape, dt, offset = raw_layout(p, dims, dtype, byte_order, header_offset)
        return _memmap_source(p, p, offset, dt, shape, "raw")
    if suffix in (".nrrd", ".nhdr"):
        pl = raw_payload(p, allow_outside=bool(allow_outside))
        return _memmap_source(p, pl.file, pl.offset, pl.dtype, pl.shape, "nrrd", pl.spacing, pl.origin,
                              pl.orientation)
    raise FileFormatError(
        f"{path!r}: not a lazily readable volume (suffix {suffix or '(none)'!r}); expected a Zarr store, "
        f"file.h5:/dataset, .npy, .raw/.bin/.dat or a raw-encoded .nrrd/.nhdr (other formats: load_volume)"
    )


def _checked_dtype(dt, where: str) -> np.dtype:
    dt = np.dtype(dt)
    if dt.kind not in "uif" or dt.fields is not None:
        raise FileFormatError(f"{where}: dtype {dt} is not a real number type; expected integers or floats")
    return dt


def _three_d(shape, where: str, what: str) -> tuple[int, int, int]:
    if len(shape) != 3:
        raise FileFormatError(f"{where}: {what} has shape {tuple(shape)}; expected a 3-D volume (nz, ny, nx)")
    if min(shape) == 0:
        raise FileFormatError(f"{where}: {what} has a zero-size axis, shape {tuple(shape)}")
    return tuple(int(n) for n in shape)  # type: ignore[return-value]


def _single_level(name: str, shape, spacing, origin) -> tuple[Level, ...]:
    return (Level(name, tuple(shape), spacing, origin),)


def _vec(values, default: float) -> np.ndarray:
    if values is None:
        return np.full(3, default)
    v = np.asarray(values, np.float64).reshape(-1)
    return v if v.shape == (3,) else np.full(3, default)


def _memmap_source(shown: Path, data_file: Path, offset: int, dt: np.dtype, shape, kind: SourceKind,
                   spacing=None, origin=None, orientation=None) -> Source:
    where = repr(str(shown))
    _checked_dtype(dt, where)
    mm = _guard(where, np.memmap, data_file, dtype=dt, mode="r", offset=offset, shape=tuple(shape), order="C")
    sp, org = _vec(spacing, 1.0), _vec(origin, 0.0)
    name = stem_of(shown)
    return Source(MemmapVoxels(mm, where), sp, org, name, shown, kind, None,
                  _single_level(name, shape, sp, org), name, orientation)


def _guard(where: str, fn: Callable, *args, **kwargs):
    try:
        return fn(*args, **kwargs)
    except SparsecastError:
        raise
    except Exception as exc:  # noqa: BLE001 - boundary: one error for every reader failure
        raise FileFormatError(f"{where}: cannot open: {type(exc).__name__}: {exc or 'no detail'} "
                              f"(file corrupt, truncated or not what its name says)") from exc


def _open_npy(p: Path) -> Source:
    where = repr(str(p))
    require_regular_file(p, ".npy file")
    mm = _guard(where, np.load, str(p), mmap_mode="r", allow_pickle=False)
    if not isinstance(mm, np.ndarray):
        raise FileFormatError(f"{where}: expected a single array in a .npy file, got {type(mm).__name__}")
    _checked_dtype(mm.dtype, where)
    shape = _three_d(mm.shape, where, "the array")
    one, zero = np.ones(3), np.zeros(3)
    name = stem_of(p)
    return Source(MemmapVoxels(mm, where), one, zero, name, p, "npy", None,
                  _single_level(name, shape, one, zero), name)


def _open_hdf5(file: Path, dataset: str | None) -> Source:
    import h5py

    where = repr(str(file))
    require_regular_file(file, "HDF5 file")
    fh = _guard(where, h5py.File, file, "r")
    try:
        found: list[tuple[str, tuple]] = []

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                found.append(("/" + name, obj.shape))

        fh.visititems(visit)
        listing = ", ".join(f"{n} {tuple(s)}" for n, s in found) or "none"
        if dataset is None or dataset in ("", "/"):
            volumes = [n for n, s in found if len(s) == 3]
            if len(volumes) != 1:
                raise FileFormatError(
                    f"{where}: holds {len(volumes)} 3-D datasets; name one as {file.name}:/path/to/dataset "
                    f"(datasets: {listing})"
                )
            dataset = volumes[0]
        obj = fh.get(dataset)
        if not isinstance(obj, h5py.Dataset):
            what = "a group" if isinstance(obj, h5py.Group) else "not found"
            raise FileFormatError(f"{where}: {dataset!r} is {what}; expected a dataset (datasets: {listing})")
        label = f"{str(file)!r}:{obj.name}"
        _checked_dtype(obj.dtype, label)
        shape = _three_d(obj.shape, label, f"dataset {obj.name!r}")
    except BaseException:
        fh.close()
        raise
    sp, org = _attr_geometry(obj.attrs)
    arr = H5Voxels(obj, label)
    name = stem_of(file)
    return Source(arr, sp, org, name, file, "hdf5", arr.chunks, _single_level(obj.name, shape, sp, org),
                  obj.name, None, _keep=fh)


def _attr_geometry(attrs) -> tuple[np.ndarray, np.ndarray]:
    """Spacing and origin ``(x, y, z)`` from attributes (``sparsecast: {spacing, origin}``,
    or ``spacing`` / ``origin`` / ``element_size_um`` (z, y, x, as ilastik writes it))."""
    ours = attrs.get(SOURCE_ATTRS) if hasattr(attrs, "get") else None
    if isinstance(ours, dict):
        return _vec(ours.get("spacing"), 1.0), _vec(ours.get("origin"), 0.0)
    sp = attrs.get("spacing") if hasattr(attrs, "get") else None
    if sp is None and hasattr(attrs, "get") and attrs.get("element_size_um") is not None:
        sp = np.asarray(attrs["element_size_um"], np.float64)[::-1]
    spacing = _vec(sp, 1.0)
    if not (np.all(np.isfinite(spacing)) and np.all(spacing > 0)):
        spacing = np.ones(3)
    origin = _vec(attrs.get("origin") if hasattr(attrs, "get") else None, 0.0)
    return spacing, origin if np.all(np.isfinite(origin)) else np.zeros(3)


def time_steps(path: str | os.PathLike, *, level: int | str | None = None) -> int:
    """Time steps of a Zarr store: the length of the ``t`` axis of its 4-D array or of
    its OME-Zarr image (an error naming the shape or axes when it has none)."""
    return _open_zarr(Path(os.fspath(path)), level, "fill", time=-1).steps


def _open_zarr(p: Path, level, missing: str, time: int | None = None) -> Source:
    import zarr

    where = repr(str(p))
    if not p.exists():
        raise FileFormatError(f"{where}: store not found")
    if not is_zarr_dir(p):
        raise FileFormatError(f"{where}: not a Zarr store (no zarr.json, .zarray or .zgroup); expected a Zarr "
                              f"v2 or v3 array or group")
    node = _guard(where, zarr.open, store=str(p), mode="r")
    name = stem_of(p)
    if missing == "auto":
        ours = node.attrs.get(SOURCE_ATTRS)
        missing = "raise" if isinstance(ours, dict) and ours.get("complete") else "fill"
    if isinstance(node, zarr.Group):
        attrs = dict(node.attrs)
        if "multiscales" in attrs or "multiscales" in attrs.get("ome", {}):
            return _open_ome(p, node, level, missing, time)
        if level is not None:
            raise ParameterError(f"level: {where} is a plain Zarr group, not an OME-Zarr multiscale image; "
                                 f"level= applies to OME-Zarr images")
        want = 3 if time is None else 4
        arrays = _guard(where, lambda: [(k, a) for k, a in node.arrays() if a.ndim == want])
        if len(arrays) != 1:
            listing = ", ".join(f"{k} {a.shape}" for k, a in sorted(_guard(where, lambda: list(node.arrays())),
                                                                      key=lambda ka: ka[0])) or "none"
            raise FileFormatError(
                f"{where}: group holds {len(arrays)} {want}-D arrays; expected one, or open the array itself "
                f"({p.name}/NAME) (arrays: {listing})"
            )
        key, node = arrays[0]
        where = repr(str(p / key))
    elif level is not None:
        raise ParameterError(f"level: {where} is a single Zarr array; level= applies to OME-Zarr images")
    _checked_dtype(node.dtype, where)
    sp, org = _attr_geometry(node.attrs)
    if time is None:
        shape = _three_d(node.shape, where, "the array")
        arr = ZarrVoxels(node, (), where, missing)
        return Source(arr, sp, org, name, p, "zarr", arr.chunks, _single_level(name, shape, sp, org), name)
    if len(node.shape) != 4:
        raise FileFormatError(f"{where}: the array has shape {tuple(node.shape)}; expected a 4-D time series "
                              "(t, nz, ny, nx)")
    _three_d(node.shape[1:], where, "a step of the array")
    levels = _single_level(name, tuple(int(n) for n in node.shape[1:]), sp, org)
    step = _step(time, int(node.shape[0]), where)
    arr = ZarrVoxels(node, (step,), f"{where} t={step}", missing)
    return Source(arr, sp, org, name, p, "zarr", arr.chunks, levels, name, steps=int(node.shape[0]))


def _step(time, n: int, where: str) -> int:
    """``time`` checked against ``n`` steps (-1: any, the count is what is asked for)."""
    if isinstance(time, bool) or not isinstance(time, (int, np.integer)) or not (-1 <= int(time) < n):
        raise ParameterError(f"time: {where} has {n} time steps (0..{n - 1}); got {time!r}")
    return max(int(time), 0)


def _ome_transform(transforms, ndim: int) -> tuple[np.ndarray, np.ndarray]:
    """Scale and translation (all axes) of a list of OME coordinate transformations."""
    scale, shift = np.ones(ndim), np.zeros(ndim)
    for t in transforms or ():
        if t.get("type") == "scale" and "scale" in t:
            s = np.asarray(t["scale"], np.float64)
            scale, shift = scale * s, shift * s
        elif t.get("type") == "translation" and "translation" in t:
            shift = shift + np.asarray(t["translation"], np.float64)
    return scale, shift


def _open_ome(p: Path, group, level, missing: str, time: int | None = None) -> Source:
    from ome_zarr.io import parse_url
    from ome_zarr.reader import Multiscales, Reader

    where = repr(str(p))
    location = _guard(where, parse_url, str(p), mode="r")
    if location is None:
        raise FileFormatError(f"{where}: ome-zarr cannot read the store")
    nodes = _guard(where, lambda: list(Reader(location)()))
    spec = next((s for n in nodes for s in n.specs if isinstance(s, Multiscales)), None)
    if spec is None:
        raise FileFormatError(f"{where}: no OME-Zarr multiscales image found; expected 'multiscales' metadata")
    node = next(n for n in nodes if spec in n.specs)
    meta = node.metadata
    declared = meta.get("axes")
    if declared is None:  # OME-NGFF before 0.3: always t, c, z, y, x
        declared = ["t", "c", "z", "y", "x"][-_guard(where, lambda: group[spec.datasets[0]]).ndim:]
    axes = [a["name"] if isinstance(a, dict) else str(a) for a in declared]
    if axes[-3:] != ["z", "y", "x"]:
        raise FileFormatError(f"{where}: OME-Zarr axes {axes}; expected the last three to be z, y, x (a 3-D image)")
    per_level = meta.get("coordinateTransformations") or [None] * len(spec.datasets)
    ms = location.root_attrs.get("multiscales", [{}])[0]
    glob_scale, glob_shift = _ome_transform(ms.get("coordinateTransformations"), len(axes))
    levels = []
    for path, transforms in zip(spec.datasets, per_level):
        arr = _guard(where, lambda: group[path])
        if arr.ndim != len(axes):
            raise FileFormatError(f"{where}: level {path!r} has {arr.ndim} axes, the metadata names {len(axes)}")
        scale, shift = _ome_transform(transforms, len(axes))
        scale, shift = scale * glob_scale, shift * glob_scale + glob_shift
        levels.append(Level(str(path), tuple(int(n) for n in arr.shape[-3:]), scale[-3:][::-1].copy(),
                            shift[-3:][::-1].copy()))
    listing = ", ".join(f"{i}: {lv.name!r} {lv.shape}" for i, lv in enumerate(levels))
    if level is None:
        chosen = 0
    elif isinstance(level, (int, np.integer)) and not isinstance(level, bool) and 0 <= int(level) < len(levels):
        chosen = int(level)
    elif isinstance(level, str) and level in [lv.name for lv in levels]:
        chosen = [lv.name for lv in levels].index(level)
    elif isinstance(level, str) and level.isdigit() and int(level) < len(levels):
        chosen = int(level)
    else:
        raise ParameterError(f"level: {where} has no level {level!r}; expected one of the levels (index: path shape) "
                             f"{listing}")
    lv = levels[chosen]
    arr = group[lv.name]
    lead = arr.shape[:-3]
    prefix = [0] * len(lead)
    if time is not None:
        if "t" not in axes[:-3]:
            raise ParameterError(f"time: {where} has axes {axes}, no t axis; time= applies to a time series")
        ti = axes.index("t")
        prefix[ti] = _step(time, int(lead[ti]), where)
    extra = [(a, n) for a, n in zip(axes[:-3], lead) if n != 1 and not (time is not None and a == "t")]
    if extra:
        raise ParameterError(
            f"{where}: axes {', '.join(f'{a} of size {n}' for a, n in extra)}; expected a single time point and "
            f"channel (size 1) for a scalar volume" + (" (open a time series with load_series)"
                                                        if any(a == "t" for a, _ in extra) else "")
        )
    label = f"{str(p)!r} level {lv.name!r}" + (f" t={prefix[axes.index('t')]}" if time is not None else "")
    _checked_dtype(arr.dtype, label)
    _three_d(arr.shape[-3:], label, "the level")
    voxels = ZarrVoxels(arr, tuple(prefix), label, missing)
    name = str(meta.get("name") or stem_of(p))
    steps = int(lead[axes.index("t")]) if "t" in axes[:-3] else 1
    return Source(voxels, lv.spacing, lv.origin, name, p, "ome-zarr", voxels.chunks, tuple(levels), lv.name,
                  steps=steps)
