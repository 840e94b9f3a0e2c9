"""Load and save volumes: :func:`load_volume` and :func:`save_volume`, dispatching on the
file name through the one table of formats (:data:`~.formats.FORMATS`).

:func:`load_volume` returns a :class:`~sparsecast.volume.Volume`; :func:`save_volume`
writes atomically (a temporary name beside the target, renamed when complete).
Every loader converts to the project's array convention: C-ordered, shape
``(nz, ny, nx)``, indexed ``[k, j, i]``, with spacing and origin in ``(x, y, z)`` order.
The supported suffixes are listed in :mod:`sparsecast.io.formats`; the readers and
writers are :mod:`.nrrd`, :mod:`.nifti`, :mod:`.raw`, :mod:`.npy` and :mod:`.tiff`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import numpy as np

from .._util.atomic import atomic_path
from .._util.checks import fail, one_of
from ..axes import check_orientation
from ..errors import FileFormatError, ParameterError, SparsecastError
from ..volume import Volume
from .formats import FORMATS, READ_SUFFIXES, WRITE_SUFFIXES
from .files import require_regular_file
from .names import stem_of, suffix_of
from .raw import RAW_DTYPES, parse_raw_name
from .reading import Read
from .tiff import read_tiff_dir
from .budget import memory_limit as default_memory_limit
from .nrrd import EncodedPayloadError
from .sources import SourceRecipe, is_lazy_path, is_zarr_dir, open_source, split_hdf5_path
from ..storage import BrickedVolume, parse_memory

__all__ = [
    "load_volume",
    "save_volume",
    "parse_raw_name",
    "READ_SUFFIXES",
    "WRITE_SUFFIXES",
    "RAW_DTYPES",
]

PathLike = str | os.PathLike


def _as_path(path) -> Path:
    """``path`` as a Path; bytes and other objects are refused by name (not a TypeError)."""
    if isinstance(path, os.PathLike):
        path = os.fspath(path)
    if not isinstance(path, str):
        raise fail("path", "a file path (str or os.PathLike)", path if isinstance(path, bytes) else type(path).__name__)
    if not path or "\x00" in path:
        raise fail("path", "a non-empty file path without NUL characters", path)
    return Path(path)


def _check_exists(path: Path) -> None:
    if not path.exists():
        raise FileFormatError(f"{str(path)!r}: file not found")


def _native(arr: np.ndarray) -> np.ndarray:
    """Return ``arr`` with a native byte order (Volume compares dtypes exactly)."""
    if arr.dtype.byteorder not in ("=", "|"):
        native = arr.dtype.newbyteorder("=")
        if arr.dtype != native:
            return arr.astype(native)
    return arr


def _make_volume(arr: np.ndarray, spacing, origin, path: Path, name: str, nonfinite, orientation) -> Volume:
    # Build with the full path as the name so data errors name the file, then relabel.
    vol = Volume(_native(np.asarray(arr)), spacing, origin, name=str(path), nonfinite=nonfinite,
                 orientation=orientation)
    vol.name = name
    return vol


def load_volume(
    path: PathLike,
    *,
    dims: tuple[int, int, int] | None = None,
    dtype: str | np.dtype | type | None = None,
    spacing: float | tuple[float, float, float] | None = None,
    origin: tuple[float, float, float] | None = None,
    byte_order: Literal["little", "big"] = "little",
    header_offset: int = 0,
    nonfinite: Literal["raise", "replace"] = "raise",
    allow_outside: bool = False,
    orientation: str | tuple[str, str, str] | None = None,
    lazy: bool | None = None,
    memory_limit: int | str | None = None,
    level: int | str | None = None,
    brick_size: int = 8,
    background: float = 0.0,
    missing_chunks: Literal["auto", "raise", "fill"] = "auto",
    progress=None,
) -> Volume:
    """Load a scalar volume from a file or store, choosing the reader from the name.

    Parameters
    ----------
    path : str or PathLike
        ``.nrrd``/``.nhdr`` (pynrrd; raw, gzip or bzip2 encoding, attached or
        detached header), ``.nii``/``.nii.gz`` (nibabel), ``.raw``/``.bin``/``.dat``
        (headerless bytes), ``.npy``, ``.tif``/``.tiff`` (multi-page stack), or a
        directory of 2-D TIFF slices (stacked in natural name order along z).
    dims : (nx, ny, nz), optional
        Raw files only: voxel counts. Default: parsed from a name like
        ``bonsai_256x256x256_uint8.raw``.
    dtype : str or dtype, optional
        Raw files only: voxel type (``uint8``, ``int8``, ``uint16``, ``int16``,
        ``uint32``, ``int32``, ``float32``/``float``, ``float64``/``double``).
        Default: parsed from the file name.
    spacing : float or (sx, sy, sz), optional
        Overrides the spacing stored in the file (default: the file's, else 1).
    origin : (ox, oy, oz), optional
        Overrides the origin stored in the file (default: the file's, else 0).
    byte_order : {"little", "big"}, optional
        Raw files only: byte order of multi-byte voxels (default little-endian).
    header_offset : int, optional
        Raw files only: bytes to skip at the start of the file.
    nonfinite : {"raise", "replace"}, optional
        NaN/Inf policy passed to :class:`~sparsecast.volume.Volume`.
    allow_outside : bool, optional
        NRRD only: read a ``data file:`` that resolves outside the header's folder
        (an absolute path, ``..``, a symlink out of it). Default False: such a header
        is refused, so a header from elsewhere cannot read arbitrary files as voxels.
    orientation : str or (3,) str, optional
        Overrides the anatomical axis codes the file stores (``"RAS"``, ``"LPS"``: where
        ``+i, +j, +k`` point in the patient), e.g. for a file that lost them (default:
        NRRD ``space`` with ``space directions``, NIfTI sform/qform when its code is set;
        other formats store none).
    lazy : bool, optional
        Return a :class:`~sparsecast.storage.BrickedVolume` that reads bricks from the
        file on demand (Zarr, OME-Zarr, ``file.h5:/dataset``, ``.npy``, raw, raw-encoded
        NRRD) instead of a dense :class:`Volume`. Default: lazy when the data is larger
        than ``memory_limit`` (or, without one, than :func:`~.budget.memory_limit`, half
        the physical memory); Zarr and HDF5 inputs read into memory otherwise.
    memory_limit : int or str, optional
        Bytes a lazy volume's resident bricks may take (``"2GB"``); also the size above
        which ``lazy=None`` goes lazy.
    level : int or str, optional
        OME-Zarr: the resolution level (index or path); default the finest.
    brick_size, background : optional
        A lazy volume's bricks (8^3 cells by default) and the value of absent bricks (0).
    missing_chunks : {"auto", "raise", "fill"}, optional
        Zarr: a chunk absent from the store is an error naming it, or reads as the fill
        value (zarr's meaning; ``write_empty_chunks=False``, zarr's default, leaves empty
        chunks out). ``"auto"`` (default): an error in stores ``sparsecast convert`` wrote
        (it writes every chunk), the fill value elsewhere.
    progress : bool or callable, optional
        A lazy volume's statistics pass: a progress bar (True) or ``progress(done, total)``.

    Returns
    -------
    Volume
        Array of shape ``(nz, ny, nx)``; ``name`` is the file stem (``brain`` for
        ``brain.nii.gz``); ``orientation`` the axis codes or None. A dense volume of a
        ``.npy`` or raw file in native byte order and a supported dtype is the file
        memory-mapped read-only (no copy); replace such a file (write a new one and
        rename it, as :func:`save_volume` does) rather than rewrite it in place while
        the volume is in use.

    Raises
    ------
    FileFormatError
        Missing file, not a regular file (a FIFO, a link to a device), unknown suffix,
        unreadable / truncated / corrupt file, a file that is not a 3-D scalar volume,
        a raw file whose size does not match ``nx*ny*nz*itemsize (+ header_offset)``,
        an unsupported raw dtype, a header that declares more data than the file holds
        or than :func:`~.budget.memory_limit` allows, a compressed payload longer or
        shorter than declared, or an NRRD data file outside the header's folder.
    VolumeDataError
        The data is unusable (zero-size axis, unsupported dtype, NaN/Inf with
        ``nonfinite="raise"``); the message names the file.
    ParameterError
        Bad ``dims``/``byte_order``/``header_offset``/``spacing``/``origin``, raw
        options given for a non-raw format, or a raw file with no dims/dtype.

    Notes
    -----
    Oblique NRRD/NIfTI orientations are not resampled: spacing is the length of
    each axis' direction vector and origin the position of voxel ``(0, 0, 0)``.

    Examples
    --------
    >>> vol = load_volume("bonsai_256x256x256_uint8.raw")          # doctest: +SKIP
    >>> vol = load_volume("ct.raw", dims=(512, 512, 300), dtype="int16",
    ...                   byte_order="big", spacing=(0.5, 0.5, 1.0))  # doctest: +SKIP
    """
    if lazy not in (None, True, False):
        raise fail("lazy", "True, False or None", lazy)
    path = str(_as_path(path))  # one check of the path for both readers
    budget = parse_memory(memory_limit)
    if split_hdf5_path(path) is not None or is_lazy_path(path) and (lazy is not False or _store_only(path)):
        source = _try_source(path, level, dims, dtype, byte_order, header_offset, allow_outside, lazy,
                             missing_chunks)
        if source is not None:
            # Cluster workers reopen the file from this instead of receiving its voxels.
            recipe = SourceRecipe(path, dict(level=level, dims=dims, dtype=dtype, byte_order=byte_order,
                                             header_offset=header_offset or 0, allow_outside=bool(allow_outside),
                                             missing_chunks=missing_chunks))
            wants_lazy = lazy if lazy is not None else source.nbytes > (budget or default_memory_limit())
            if wants_lazy:
                sp = spacing if spacing is not None else source.spacing
                org = origin if origin is not None else source.origin
                vol = BrickedVolume(source.array, sp, org, name=source.name, brick_size=brick_size,
                                    background=background, memory_limit=budget, nonfinite=nonfinite,
                                    orientation=orientation if orientation is not None else source.orientation,
                                    progress=progress)
                vol.source_recipe = recipe
                return vol
            if source.kind in _MAPPED:
                # The dense volume's voxels are the read-only memory map itself: no copy
                # (np.load / np.fromfile copied 1 GiB from the page cache in 0.15-0.3 s),
                # the pages arrive as the brick statistics read them, on every core.
                vol = _make_volume(source.array[...], spacing if spacing is not None else 1.0,
                                   origin if origin is not None else 0.0, source.path, source.name,
                                   nonfinite, orientation)
                if nonfinite == "raise" or vol.dtype.kind != "f":  # else the volume holds replaced values
                    vol.source_recipe = recipe
                return vol
            if _store_only(path):  # Zarr / HDF5 that fits: read it into a dense volume
                sp = spacing if spacing is not None else source.spacing
                org = origin if origin is not None else source.origin
                return _make_volume(source.array[:, :, :], sp, org, source.path, source.name, nonfinite,
                                    orientation if orientation is not None else source.orientation)
    elif level is not None:
        raise ParameterError(f"level: {str(path)!r} has a single resolution level; level= applies to OME-Zarr images")
    p = _as_path(path)
    _check_exists(p)
    one_of(nonfinite, "nonfinite", ("raise", "replace"), expected="'raise' or 'replace'")

    suffix = suffix_of(p)
    fmt = None if p.is_dir() else FORMATS.get(suffix)
    if fmt is None or not fmt.raw_layout:
        extra = [n for n, v in (("dims", dims), ("dtype", dtype)) if v is not None]
        if header_offset is not None and not (isinstance(header_offset, (int, np.integer))
                                                and not isinstance(header_offset, bool) and header_offset == 0):
            extra.append("header_offset")
        if extra:
            raise ParameterError(
                f"{', '.join(extra)}: {'applies' if len(extra) == 1 else 'apply'} only to raw files "
                f"(.raw/.bin/.dat), not {str(p)!r}"
            )

    orientation = check_orientation(orientation)  # before any work
    if p.is_dir():
        read = Read(*read_tiff_dir(p))
        name = p.name or str(p)
    elif fmt is None:
        raise FileFormatError(
            f"{str(p)!r}: unknown volume file suffix {suffix or '(none)'!r}; "
            f"supported: {', '.join(READ_SUFFIXES)} or a directory of TIFF slices"
        )
    else:
        require_regular_file(p, "volume file")  # a FIFO blocks, /dev/zero never ends
        name = stem_of(p)
        if fmt.raw_layout:
            read = Read(*fmt.read(p, dims, dtype, byte_order, header_offset))
        elif fmt.data_file:
            read = Read(*fmt.read(p, allow_outside=bool(allow_outside)))
        else:
            read = Read(*fmt.read(p))

    sp = spacing if spacing is not None else (read.spacing if read.spacing is not None else 1.0)
    org = origin if origin is not None else (read.origin if read.origin is not None else 0.0)
    return _make_volume(read.data, sp, org, p, name, nonfinite,
                        orientation if orientation is not None else read.orientation)


#: sources whose dense volume maps the file instead of reading it (headerless voxels
#: and .npy: no spacing, origin or orientation in the file)
_MAPPED = ("npy", "raw")


def _store_only(path) -> bool:
    """Zarr stores and HDF5 files: formats only :func:`~.sources.open_source` reads."""
    if split_hdf5_path(path) is not None:
        return True
    p = Path(os.fspath(path))
    return is_zarr_dir(p) or suffix_of(p) in (".zarr", ".h5", ".hdf5")


def _try_source(path, level, dims, dtype, byte_order, header_offset, allow_outside, lazy, missing_chunks):
    """The lazy source of ``path``, or None where the dense reader should take it: a gzip
    NRRD, or a file the source cannot open when laziness was not asked for (``lazy=True``
    and Zarr / HDF5 raise the source's error)."""
    try:
        return open_source(path, level=level, dims=dims, dtype=dtype, byte_order=byte_order,
                           header_offset=header_offset or 0, allow_outside=bool(allow_outside),
                           missing_chunks=missing_chunks)
    except EncodedPayloadError:
        if lazy:
            raise
        return None
    except SparsecastError:
        if lazy or _store_only(path):
            raise
        return None  # the dense reader has the same complaint, in the words tests and users know


def save_volume(volume: Volume, path: PathLike, *, compress: bool = True) -> Path:
    """Write a volume, choosing the format from the file name; atomic.

    Parameters
    ----------
    volume : Volume
        The volume to write (its dtype is kept).
    path : str or PathLike
        Target file: ``.nrrd`` (axes x y z, ``space directions`` = diag(spacing),
        ``space origin``), ``.nii``/``.nii.gz`` (affine = diag(spacing) + origin),
        ``.npy`` (array ``(nz, ny, nx)`` only), ``.tif``/``.tiff`` (one page per z
        slice; no spacing) or ``.raw`` (little-endian bytes, x fastest; no
        spacing). For raw files use the name convention
        ``name_{nx}x{ny}x{nz}_{dtype}.raw`` (e.g. ``bonsai_256x256x256_uint8.raw``)
        so :func:`load_volume` can read it back without extra arguments; a name
        following the convention must agree with the volume.
    compress : bool, optional
        ``.nrrd``: gzip encoding (default) or raw. Ignored for other formats
        (``.nii.gz`` is always compressed, ``.nii`` never).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    FileFormatError
        Unknown suffix, a raw name that contradicts the volume, or an OS error
        while writing (nothing is left at ``path`` then).
    ParameterError
        The target directory does not exist.
    """
    if not isinstance(volume, Volume):
        raise ParameterError(f"volume: expected a Volume, got {type(volume).__name__}")
    p = Path(path)
    suffix = suffix_of(p)
    fmt = FORMATS.get(suffix)
    if fmt is None or fmt.write is None:
        raise FileFormatError(
            f"{str(p)!r}: cannot write volume files with suffix {suffix or '(none)'!r}; "
            f"supported: {', '.join(WRITE_SUFFIXES)}"
        )
    if fmt.check_target is not None:
        fmt.check_target(volume, p)
    try:
        with atomic_path(p) as tmp:
            fmt.write(volume, tmp, compress)
    except OSError as exc:
        raise FileFormatError(f"{str(p)!r}: cannot write: {type(exc).__name__}: {exc}") from exc
    return p
