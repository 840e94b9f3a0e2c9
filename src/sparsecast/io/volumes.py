"""Volume readers and writers: NRRD, NIfTI, raw bricks, ``.npy`` and TIFF stacks.

One entry point each way: :func:`load_volume` picks the reader from the file name and
returns a :class:`~sparsecast.volume.Volume`; :func:`save_volume` picks the writer from
the file name and writes atomically (a temporary name beside the target, renamed when
complete).

Every loader converts to the project's array convention: C-ordered, shape
``(nz, ny, nx)``, indexed ``[k, j, i]``, with spacing and origin in ``(x, y, z)`` order.

Supported suffixes
------------------
============== ====== ====== ==========================================================
suffix         read   write  notes
============== ====== ====== ==========================================================
``.nrrd``      yes    yes    raw / gzip / bzip2 encodings; spacing from ``space
                             directions`` (vector norms) or ``spacings``
``.nhdr``      yes    no     detached header, data file resolved relative to it
``.nii``       yes    yes    on-disk dtype kept; ``scl_slope``/``scl_inter`` applied
``.nii.gz``    yes    yes    when set and non-trivial
``.raw``       yes    yes    dims/dtype explicit or from ``name_XxYxZ_dtype.raw``
``.bin``       yes    no     same as ``.raw``
``.dat``       yes    no     same as ``.raw``
``.npy``       yes    yes    ``allow_pickle=False``
``.tif(f)``    yes    yes    multi-page stack or 3-D array; a directory of 2-D slices
                             (sorted by name) is read as a stack too
============== ====== ====== ==========================================================
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Literal

import numpy as np

from ..errors import FileFormatError, ParameterError, SparsecastError
from ..volume import Volume
from .._atomic import atomic_path

__all__ = [
    "load_volume",
    "save_volume",
    "parse_raw_name",
    "READ_SUFFIXES",
    "WRITE_SUFFIXES",
    "RAW_DTYPES",
]

PathLike = str | os.PathLike

#: Suffixes :func:`load_volume` understands (besides a directory of TIFF slices).
READ_SUFFIXES: tuple[str, ...] = (
    ".nrrd", ".nhdr", ".nii", ".nii.gz", ".raw", ".bin", ".dat", ".npy", ".tif", ".tiff",
)
#: Suffixes :func:`save_volume` can write.
WRITE_SUFFIXES: tuple[str, ...] = (".nrrd", ".nii", ".nii.gz", ".raw", ".npy", ".tif", ".tiff")

_RAW_SUFFIXES = (".raw", ".bin", ".dat")
_TIFF_SUFFIXES = (".tif", ".tiff")

#: dtype spellings accepted for raw files (explicit ``dtype=`` or the file name).
#: Types other than uint8/uint16/int16/float32/float64 are converted losslessly by
#: :class:`~sparsecast.volume.Volume`.
RAW_DTYPES: dict[str, np.dtype] = {
    "uint8": np.dtype(np.uint8),
    "u8": np.dtype(np.uint8),
    "uchar": np.dtype(np.uint8),
    "ubyte": np.dtype(np.uint8),
    "int8": np.dtype(np.int8),
    "i8": np.dtype(np.int8),
    "char": np.dtype(np.int8),
    "byte": np.dtype(np.int8),
    "uint16": np.dtype(np.uint16),
    "u16": np.dtype(np.uint16),
    "ushort": np.dtype(np.uint16),
    "int16": np.dtype(np.int16),
    "i16": np.dtype(np.int16),
    "short": np.dtype(np.int16),
    "uint32": np.dtype(np.uint32),
    "u32": np.dtype(np.uint32),
    "uint": np.dtype(np.uint32),
    "int32": np.dtype(np.int32),
    "i32": np.dtype(np.int32),
    "int": np.dtype(np.int32),
    "float32": np.dtype(np.float32),
    "f32": np.dtype(np.float32),
    "float": np.dtype(np.float32),
    "float64": np.dtype(np.float64),
    "f64": np.dtype(np.float64),
    "double": np.dtype(np.float64),
}

# name_XxYxZ_dtype.raw (dtype optional: name_XxYxZ.raw)
_RAW_NAME_RE = re.compile(r"(?:^|[_\-.])(\d+)x(\d+)x(\d+)(?:[_\-.]([A-Za-z][A-Za-z0-9]*))?$", re.IGNORECASE)


# -------------------------------------------------------------------------------------
# helpers
# -------------------------------------------------------------------------------------
def _suffix(path: Path) -> str:
    """Lower-case format suffix, with ``.nii.gz`` treated as one suffix."""
    name = path.name.lower()
    if name.endswith(".nii.gz"):
        return ".nii.gz"
    return path.suffix.lower()


def _stem(path: Path) -> str:
    """File name without its format suffix (``brain.nii.gz`` -> ``brain``)."""
    suffix = _suffix(path)
    if suffix and path.name.lower().endswith(suffix):
        return path.name[: len(path.name) - len(suffix)] or path.name
    return path.stem or path.name


def _native(arr: np.ndarray) -> np.ndarray:
    """Return ``arr`` with a native byte order (Volume compares dtypes exactly)."""
    if arr.dtype.byteorder not in ("=", "|"):
        native = arr.dtype.newbyteorder("=")
        if arr.dtype != native:
            return arr.astype(native)
    return arr


def _raw_dtype(spec, where: str) -> np.dtype:
    """Resolve a raw dtype spelling or dtype object; reject what Volume cannot hold."""
    if isinstance(spec, str):
        key = spec.strip().lower()
        if key in RAW_DTYPES:
            return RAW_DTYPES[key]
        found = spec
    else:
        try:
            dt = np.dtype(spec)
        except TypeError as exc:
            raise ParameterError(f"{where}: cannot interpret dtype {spec!r}") from exc
        dt = dt.newbyteorder("=") if dt.byteorder not in ("=", "|") else dt
        if dt in set(RAW_DTYPES.values()):
            return dt
        found = str(dt)
    supported = "uint8, int8, uint16, int16, uint32, int32, float32 (float), float64 (double)"
    raise FileFormatError(f"{where}: unsupported dtype {found!r}; expected one of {supported}")


def _check_exists(path: Path) -> None:
    if not path.exists():
        raise FileFormatError(f"{str(path)!r}: file not found")


def _read_error(path: Path, exc: BaseException, what: str = "") -> FileFormatError:
    detail = str(exc) or type(exc).__name__
    kind = f" as {what}" if what else ""
    return FileFormatError(
        f"{str(path)!r}: cannot read{kind}: {type(exc).__name__}: {detail} "
        f"(file corrupt, truncated or not in the format its name says)"
    )


def _read_guard(path: Path, what: str, fn, *args, **kwargs):
    """Call a library reader; turn any library exception into FileFormatError."""
    try:
        return fn(*args, **kwargs)
    except (SparsecastError, MemoryError, KeyboardInterrupt):
        raise
    except Exception as exc:  # noqa: BLE001 - boundary: every library error is reported alike
        raise _read_error(path, exc, what) from exc


def _make_volume(arr: np.ndarray, spacing, origin, path: Path, name: str, nonfinite) -> Volume:
    # Build with the full path as the name so data errors name the file, then relabel.
    vol = Volume(_native(np.asarray(arr)), spacing, origin, name=str(path), nonfinite=nonfinite)
    vol.name = name
    return vol


def parse_raw_name(path: PathLike) -> tuple[tuple[int, int, int], np.dtype] | None:
    """Parse the common raw-volume naming convention ``name_XxYxZ_dtype.raw``.

    Parameters
    ----------
    path : str or PathLike
        A file name such as ``bonsai_256x256x256_uint8.raw``.

    Returns
    -------
    ((nx, ny, nz), dtype) or None
        Dimensions in ``(x, y, z)`` order and the (native byte order) dtype, or
        ``None`` when the name has no ``XxYxZ_dtype`` part.

    Raises
    ------
    FileFormatError
        The name has the ``XxYxZ_<type>`` form but ``<type>`` is not a supported
        dtype (e.g. ``complex64``), or a dimension is zero.

    Examples
    --------
    >>> parse_raw_name("bonsai_256x256x256_uint8.raw")
    ((256, 256, 256), dtype('uint8'))
    >>> parse_raw_name("volume.raw") is None
    True
    """
    p = Path(path)
    m = _RAW_NAME_RE.search(_stem(p))
    if m is None or m.group(4) is None:
        return None
    dims = (int(m.group(1)), int(m.group(2)), int(m.group(3)))
    if min(dims) == 0:
        raise FileFormatError(f"{str(p)!r}: file name gives a zero dimension {dims}")
    return dims, _raw_dtype(m.group(4), f"{str(p)!r} (dtype from file name)")


def _parse_raw_dims_only(path: Path) -> tuple[int, int, int] | None:
    m = _RAW_NAME_RE.search(_stem(path))
    if m is None:
        return None
    return (int(m.group(1)), int(m.group(2)), int(m.group(3)))


# -------------------------------------------------------------------------------------
# readers: each returns (array (nz, ny, nx), spacing or None, origin or None)
# -------------------------------------------------------------------------------------
def _read_nrrd(path: Path):
    import nrrd

    def _read():
        with open(path, "rb") as fh:
            header = nrrd.read_header(fh)
            dim = int(header.get("dimension", len(header.get("sizes", []))))
            sizes = [int(s) for s in header.get("sizes", [])]
            if dim != 3:
                raise FileFormatError(
                    f"{str(path)!r}: {dim}-D NRRD with sizes {sizes}; expected a 3-D scalar volume"
                )
            kinds = header.get("kinds")
            if kinds is not None:
                bad = [k for k in kinds if str(k).lower() not in ("domain", "space", "time", "none", "???")]
                if bad:
                    raise FileFormatError(
                        f"{str(path)!r}: non-scalar NRRD (axis kinds {list(kinds)}); "
                        f"expected a 3-D scalar volume with kinds 'domain' or 'space'"
                    )
            data = nrrd.read_data(header, fh, str(path), index_order="C")
        return data, header

    data, header = _read_guard(path, "NRRD", _read)

    spacing = None
    dirs = header.get("space directions")
    if dirs is not None:
        dirs = np.asarray(dirs, dtype=np.float64)
        if dirs.ndim == 2 and dirs.shape[0] == 3:
            norms = np.linalg.norm(dirs, axis=1)
            if np.all(np.isfinite(norms)) and np.all(norms > 0):
                spacing = norms
    if spacing is None and header.get("spacings") is not None:
        sp = np.asarray(header["spacings"], dtype=np.float64)
        if sp.shape == (3,) and np.all(np.isfinite(sp)) and np.all(sp > 0):
            spacing = sp
    origin = None
    org = header.get("space origin")
    if org is not None:
        org = np.asarray(org, dtype=np.float64).ravel()
        if org.shape == (3,) and np.all(np.isfinite(org)):
            origin = org
    return data, spacing, origin


def _read_nifti(path: Path):
    import nibabel as nib

    def _read():
        img = nib.load(str(path), mmap=False)
        dataobj = img.dataobj
        if nib.is_proxy(dataobj):
            # nibabel moves scl_slope/scl_inter from the header into the proxy on load
            # (the image's header then reads NaN), so take them from the proxy.
            raw = np.asarray(dataobj.get_unscaled())
            slope = getattr(dataobj, "slope", None)
            inter = getattr(dataobj, "inter", None)
        else:
            raw = np.asanyarray(dataobj)
            slope, inter = img.header.get_slope_inter()
        zooms = img.header.get_zooms()
        return img, np.array(raw), slope, inter, zooms

    img, raw, slope, inter, zooms = _read_guard(path, "NIfTI", _read)
    # Drop trailing singleton axes (x, y, z, 1) which are common in the wild.
    while raw.ndim > 3 and raw.shape[-1] == 1:
        raw = raw[..., 0]
    if raw.ndim != 3:
        raise FileFormatError(
            f"{str(path)!r}: {raw.ndim}-D NIfTI image of shape {raw.shape}; expected a 3-D scalar volume"
        )
    slope = None if slope is None or not np.isfinite(float(slope)) else float(slope)
    inter = None if inter is None or not np.isfinite(float(inter)) else float(inter)
    if (slope not in (None, 0.0, 1.0)) or (inter not in (None, 0.0)):
        out_dtype = np.result_type(raw.dtype, np.float32)
        s = 1.0 if slope in (None, 0.0) else slope
        i = 0.0 if inter is None else inter
        raw = raw.astype(out_dtype) * out_dtype.type(s) + out_dtype.type(i)
    data = np.ascontiguousarray(raw.transpose(2, 1, 0))  # (x, y, z) -> (z, y, x)
    spacing = np.asarray(zooms[:3], dtype=np.float64)
    if spacing.shape != (3,) or not np.all(np.isfinite(spacing)) or np.any(spacing <= 0):
        spacing = None
    origin = np.asarray(img.affine, dtype=np.float64)[:3, 3]
    if not np.all(np.isfinite(origin)):
        origin = None
    return data, spacing, origin


def _read_raw(path: Path, dims, dtype, byte_order: str, header_offset: int):
    where = repr(str(path))
    if dims is None or dtype is None:
        parsed_dims = _parse_raw_dims_only(path)
        parsed = parse_raw_name(path) if dtype is None else None
        if dims is None:
            dims = parsed[0] if parsed is not None else parsed_dims
        if dtype is None and parsed is not None:
            dtype = parsed[1]
        if dims is None or dtype is None:
            missing = " and ".join(n for n, v in (("dims", dims), ("dtype", dtype)) if v is None)
            raise ParameterError(
                f"{where}: raw file needs {missing}; pass dims=(nx, ny, nz) and dtype=..., "
                f"or name the file like 'name_256x256x128_uint8.raw'"
            )
    try:
        nx, ny, nz = (int(d) for d in dims)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"dims: expected 3 integers (nx, ny, nz), got {dims!r}") from exc
    if min(nx, ny, nz) <= 0:
        raise ParameterError(f"dims: expected positive integers (nx, ny, nz), got {(nx, ny, nz)}")
    dt = _raw_dtype(dtype, f"{where} dtype")
    if byte_order not in ("little", "big"):
        raise ParameterError(f"byte_order: expected 'little' or 'big', got {byte_order!r}")
    dt = dt.newbyteorder("<" if byte_order == "little" else ">")
    header_offset = int(header_offset)
    if header_offset < 0:
        raise ParameterError(f"header_offset: expected an integer >= 0, got {header_offset}")
    expected = nx * ny * nz * dt.itemsize + header_offset
    size = path.stat().st_size
    if size != expected:
        extra = f" + {header_offset} header bytes" if header_offset else ""
        raise FileFormatError(
            f"{where}: file size is {size} bytes, expected {expected} bytes "
            f"({nx}x{ny}x{nz} voxels of {dt.name}, {dt.itemsize} byte(s) each{extra})"
        )
    arr = _read_guard(
        path, "raw", np.fromfile, str(path), dtype=dt, count=nx * ny * nz, offset=header_offset
    )
    if arr.size != nx * ny * nz:
        raise FileFormatError(f"{where}: read {arr.size} voxels, expected {nx * ny * nz}")
    return arr.reshape(nz, ny, nx), None, None


def _read_npy(path: Path):
    arr = _read_guard(path, "NumPy .npy", np.load, str(path), allow_pickle=False)
    if not isinstance(arr, np.ndarray):
        raise FileFormatError(f"{str(path)!r}: expected a single array in a .npy file, got {type(arr).__name__}")
    return arr, None, None


def _tiff_to_3d(arr: np.ndarray, axes: str, path: Path) -> np.ndarray:
    if "S" in axes.upper() and arr.ndim >= 3:
        raise FileFormatError(
            f"{str(path)!r}: TIFF with colour samples (axes {axes!r}, shape {arr.shape}); "
            f"expected a grayscale 3-D stack (a 3- or 4-slice stack written by tifffile "
            f"without photometric='minisblack' is stored as colour; rewrite it with that option)"
        )
    if arr.ndim > 3:
        arr = arr.reshape([s for s in arr.shape if s != 1] or [1])
    if arr.ndim == 2:
        raise FileFormatError(
            f"{str(path)!r}: single 2-D TIFF image of shape {arr.shape}; expected a 3-D stack "
            f"(a multi-page TIFF, or a directory of 2-D slices)"
        )
    if arr.ndim != 3:
        raise FileFormatError(f"{str(path)!r}: TIFF of shape {arr.shape}; expected a 3-D stack")
    return arr


def _read_tiff(path: Path):
    import tifffile

    def _read():
        with tifffile.TiffFile(str(path)) as tf:
            if not tf.series:
                raise FileFormatError(f"{str(path)!r}: TIFF file holds no image series")
            series = tf.series[0]
            return series.asarray(), series.axes

    arr, axes = _read_guard(path, "TIFF", _read)
    return _tiff_to_3d(np.asarray(arr), axes, path), None, None


def _natural_key(p: Path):
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", p.name)]


def _read_tiff_dir(path: Path):
    import tifffile

    files = sorted(
        (f for f in path.iterdir() if f.is_file() and f.suffix.lower() in _TIFF_SUFFIXES),
        key=_natural_key,
    )
    if not files:
        raise FileFormatError(
            f"{str(path)!r}: directory holds no .tif/.tiff slices; a directory is read as a stack "
            f"of 2-D TIFF slices"
        )
    slices = []
    for f in files:
        img = np.asarray(_read_guard(f, "TIFF", tifffile.imread, str(f)))
        if img.ndim != 2:
            raise FileFormatError(f"{str(f)!r}: slice of shape {img.shape}; expected a 2-D grayscale image")
        if slices and (img.shape != slices[0].shape or img.dtype != slices[0].dtype):
            raise FileFormatError(
                f"{str(f)!r}: slice is {img.shape} {img.dtype}, expected {slices[0].shape} "
                f"{slices[0].dtype} like {files[0].name!r}"
            )
        slices.append(img)
    return np.stack(slices, axis=0), None, None


# -------------------------------------------------------------------------------------
# public API
# -------------------------------------------------------------------------------------
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
) -> Volume:
    """Load a scalar volume from a file, choosing the reader from the file name.

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

    Returns
    -------
    Volume
        Array of shape ``(nz, ny, nx)``; ``name`` is the file stem (``brain`` for
        ``brain.nii.gz``).

    Raises
    ------
    FileFormatError
        Missing file, unknown suffix, unreadable / truncated / corrupt file, a file
        that is not a 3-D scalar volume, a raw file whose size does not match
        ``nx*ny*nz*itemsize (+ header_offset)``, or an unsupported raw dtype.
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
    p = Path(path)
    _check_exists(p)
    if nonfinite not in ("raise", "replace"):
        raise ParameterError(f"nonfinite: expected 'raise' or 'replace', got {nonfinite!r}")

    suffix = _suffix(p)
    is_raw = (not p.is_dir()) and suffix in _RAW_SUFFIXES
    if not is_raw:
        extra = [n for n, v in (("dims", dims), ("dtype", dtype)) if v is not None]
        if header_offset:
            extra.append("header_offset")
        if extra:
            raise ParameterError(
                f"{', '.join(extra)}: only apply to raw files (.raw/.bin/.dat), not {str(p)!r}"
            )

    if p.is_dir():
        arr, f_spacing, f_origin = _read_tiff_dir(p)
        name = p.name or str(p)
    else:
        name = _stem(p)
        if suffix in (".nrrd", ".nhdr"):
            arr, f_spacing, f_origin = _read_nrrd(p)
        elif suffix in (".nii", ".nii.gz"):
            arr, f_spacing, f_origin = _read_nifti(p)
        elif is_raw:
            arr, f_spacing, f_origin = _read_raw(p, dims, dtype, byte_order, header_offset)
        elif suffix == ".npy":
            arr, f_spacing, f_origin = _read_npy(p)
        elif suffix in _TIFF_SUFFIXES:
            arr, f_spacing, f_origin = _read_tiff(p)
        else:
            raise FileFormatError(
                f"{str(p)!r}: unknown volume file suffix {suffix or '(none)'!r}; "
                f"supported: {', '.join(READ_SUFFIXES)} or a directory of TIFF slices"
            )

    sp = spacing if spacing is not None else (f_spacing if f_spacing is not None else 1.0)
    org = origin if origin is not None else (f_origin if f_origin is not None else 0.0)
    return _make_volume(arr, sp, org, p, name, nonfinite)


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
    suffix = _suffix(p)
    if suffix not in WRITE_SUFFIXES:
        raise FileFormatError(
            f"{str(p)!r}: cannot write volume files with suffix {suffix or '(none)'!r}; "
            f"supported: {', '.join(WRITE_SUFFIXES)}"
        )
    data = volume.data
    if suffix == ".raw":
        parsed = parse_raw_name(p)
        if parsed is not None and (parsed[0] != volume.dims or parsed[1] != data.dtype):
            nx, ny, nz = parsed[0]
            raise FileFormatError(
                f"{str(p)!r}: file name says {nx}x{ny}x{nz} {parsed[1]}, but the volume is "
                f"{'x'.join(map(str, volume.dims))} {data.dtype}"
            )

    try:
        with atomic_path(p) as tmp:
            if suffix == ".nrrd":
                _write_nrrd(volume, tmp, compress)
            elif suffix in (".nii", ".nii.gz"):
                _write_nifti(volume, tmp)
            elif suffix == ".npy":
                with open(tmp, "wb") as fh:
                    np.save(fh, data, allow_pickle=False)
            elif suffix in _TIFF_SUFFIXES:
                import tifffile

                tifffile.imwrite(str(tmp), data, photometric="minisblack")
            else:  # .raw
                with open(tmp, "wb") as fh:
                    fh.write(data.astype(data.dtype.newbyteorder("<"), copy=False).tobytes(order="C"))
    except OSError as exc:
        raise FileFormatError(f"{str(p)!r}: cannot write: {type(exc).__name__}: {exc}") from exc
    return p


def _write_nrrd(volume: Volume, tmp: Path, compress: bool) -> None:
    import nrrd

    header = {
        "space dimension": 3,
        "space directions": np.diag(volume.spacing.astype(np.float64)),
        "space origin": volume.origin.astype(np.float64),
        "kinds": ["domain", "domain", "domain"],
        "encoding": "gzip" if compress else "raw",
    }
    # index_order='C': array (nz, ny, nx) -> sizes "nx ny nz", x fastest, as NRRD expects.
    nrrd.write(str(tmp), np.ascontiguousarray(volume.data), header, index_order="C", compression_level=6)


def _write_nifti(volume: Volume, tmp: Path) -> None:
    import nibabel as nib

    affine = np.diag(np.append(volume.spacing.astype(np.float64), 1.0))
    affine[:3, 3] = volume.origin
    img = nib.Nifti1Image(np.asarray(volume.data).transpose(2, 1, 0), affine)  # (z,y,x) -> (x,y,z)
    img.header.set_data_dtype(volume.data.dtype)
    img.header.set_xyzt_units("mm")
    nib.save(img, str(tmp))
