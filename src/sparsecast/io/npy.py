"""NumPy ``.npy`` volumes: the array ``(nz, ny, nx)`` itself, no spacing or origin."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from ..volume import Volume
from .budget import check_declared
from .files import file_size, require_regular_file
from .reading import Read, read_guard

__all__ = ["read_npy", "read_npy_array", "write_npy"]


def read_npy(path: Path) -> Read:
    """One array from a ``.npy`` file (``allow_pickle=False``), taken as ``(nz, ny, nx)``."""
    return read_npy_array(path), None, None


def read_npy_array(path: Path, what: str = "NumPy .npy") -> np.ndarray:
    """The array of a ``.npy`` file, after its header's shape and dtype are checked
    against the file size and the memory limit (a 100-byte file can claim 909 TiB).

    Raises
    ------
    FileFormatError
        Not a ``.npy`` file, an object (pickled) array, or a header that claims more
        data than the file holds or memory takes.
    """
    npformat = np.lib.format
    require_regular_file(path, ".npy file")

    def _header():
        with open(path, "rb") as fh:
            version = npformat.read_magic(fh)
            if version == (1, 0):
                shape, _, dtype = npformat.read_array_header_1_0(fh)
            elif version == (2, 0):
                shape, _, dtype = npformat.read_array_header_2_0(fh)
            else:
                raise FileFormatError(f"{str(path)!r}: .npy format version {version}; expected 1.0 or 2.0")
            return shape, dtype, fh.tell()

    shape, dtype, offset = read_guard(path, what, _header)
    if dtype.hasobject:
        raise FileFormatError(
            f"{str(path)!r}: .npy array of Python objects (dtype {dtype}); expected numbers "
            "(pickled data is never loaded)"
        )
    declared = math.prod(shape) * dtype.itemsize
    check_declared(path, declared, f".npy header (shape {shape}, {dtype})", available=file_size(path) - offset)
    arr = read_guard(path, what, np.load, str(path), allow_pickle=False)
    if not isinstance(arr, np.ndarray):
        raise FileFormatError(f"{str(path)!r}: expected a single array in a .npy file, got {type(arr).__name__}")
    return arr


def write_npy(volume: Volume, tmp: Path, compress: bool) -> None:
    """The array ``(nz, ny, nx)`` (``compress`` is ignored)."""
    with open(tmp, "wb") as fh:
        np.save(fh, volume.data, allow_pickle=False)
