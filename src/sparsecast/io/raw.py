"""Raw volumes (``.raw``, ``.bin``, ``.dat``): headerless voxels whose layout comes from
the caller or from the file name convention ``name_XxYxZ_dtype.raw``."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from .._util.checks import as_int, fail, one_of
from ..errors import FileFormatError, ParameterError
from ..volume import Volume
from .names import stem_of
from .budget import check_declared
from .files import file_size, require_regular_file
from .reading import Read, read_guard

__all__ = ["RAW_DTYPES", "parse_raw_name", "raw_dtype", "raw_layout", "read_raw", "write_raw", "check_raw_name"]

PathLike = str | os.PathLike

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


def raw_dtype(spec, where: str) -> np.dtype:
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
    m = _RAW_NAME_RE.search(stem_of(p))
    if m is None or m.group(4) is None:
        return None
    dims = (int(m.group(1)), int(m.group(2)), int(m.group(3)))
    if min(dims) == 0:
        raise FileFormatError(f"{str(p)!r}: file name gives a zero dimension {dims}")
    return dims, raw_dtype(m.group(4), f"{str(p)!r} (dtype from file name)")


def _parse_dims_only(path: Path) -> tuple[int, int, int] | None:
    """``XxYxZ`` from the file name, with or without a dtype after it."""
    m = _RAW_NAME_RE.search(stem_of(path))
    if m is None:
        return None
    return (int(m.group(1)), int(m.group(2)), int(m.group(3)))


def read_raw(path: Path, dims=None, dtype=None, byte_order: str = "little", header_offset: int = 0) -> Read:
    """Headerless voxels, x fastest: ``dims``/``dtype`` given, or parsed from the file name.

    The file size must be exactly ``nx*ny*nz*itemsize + header_offset``.
    """
    shape, dt, header_offset = raw_layout(path, dims, dtype, byte_order, header_offset)
    nz, ny, nx = shape
    check_declared(path, nx * ny * nz * dt.itemsize, f"raw layout {nx}x{ny}x{nz} {dt.name}")
    arr = read_guard(
        path, "raw", np.fromfile, str(path), dtype=dt, count=nx * ny * nz, offset=header_offset
    )
    if arr.size != nx * ny * nz:
        raise FileFormatError(f"{repr(str(path))}: read {arr.size} voxels, expected {nx * ny * nz}")
    return arr.reshape(nz, ny, nx), None, None


def raw_layout(path: Path, dims=None, dtype=None, byte_order: str = "little",
               header_offset: int = 0) -> tuple[tuple[int, int, int], np.dtype, int]:
    """Where a raw file's voxels lie: ``((nz, ny, nx), dtype with byte order, offset)``.

    ``dims``/``dtype`` as :func:`read_raw` takes them (or parsed from the file name);
    the file size must be exactly ``nx*ny*nz*itemsize + header_offset``. Nothing is
    read, so a memory map (:func:`sparsecast.io.sources.open_source`) may use it for a
    file of any size.

    Raises
    ------
    ParameterError
        No dims/dtype given or in the name, bad dims, byte order or offset.
    FileFormatError
        Not a regular file, an unsupported dtype, or a size that does not match.
    """
    where = repr(str(path))
    if dims is None or dtype is None:
        parsed_dims = _parse_dims_only(path)
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
        nx, ny, nz = (as_int(d, "dims") for d in dims)
    except (TypeError, ValueError, ParameterError):  # not iterable, not 3, not integers
        raise fail("dims", "3 integers (nx, ny, nz)", dims) from None
    if min(nx, ny, nz) <= 0:
        raise fail("dims", "positive integers (nx, ny, nz)", (nx, ny, nz))
    dt = raw_dtype(dtype, f"{where} dtype")
    one_of(byte_order, "byte_order", ("little", "big"), expected="'little' or 'big'")
    dt = dt.newbyteorder("<" if byte_order == "little" else ">")
    header_offset = as_int(header_offset, "header_offset", lo=0)
    expected = nx * ny * nz * dt.itemsize + header_offset
    size = file_size(require_regular_file(path, "raw volume file"))
    if size != expected:
        extra = f" + {header_offset} header bytes" if header_offset else ""
        raise FileFormatError(
            f"{where}: file size is {size} bytes, expected {expected} bytes "
            f"({nx}x{ny}x{nz} voxels of {dt.name}, {dt.itemsize} byte(s) each{extra})"
        )
    return (nz, ny, nx), dt, header_offset


def check_raw_name(volume: Volume, target: Path) -> None:
    """A target named like ``name_XxYxZ_dtype.raw`` must agree with the volume (so that
    :func:`read_raw` reads back what was written)."""
    parsed = parse_raw_name(target)
    data = volume.data
    if parsed is not None and (parsed[0] != volume.dims or parsed[1] != data.dtype):
        nx, ny, nz = parsed[0]
        raise FileFormatError(
            f"{str(target)!r}: file name says {nx}x{ny}x{nz} {parsed[1]}, but the volume is "
            f"{'x'.join(map(str, volume.dims))} {data.dtype}"
        )


def write_raw(volume: Volume, tmp: Path, compress: bool) -> None:
    """Little-endian voxels, x fastest; no header, spacing or origin (``compress`` is ignored)."""
    data = volume.data
    with open(tmp, "wb") as fh:
        fh.write(data.astype(data.dtype.newbyteorder("<"), copy=False).tobytes(order="C"))
