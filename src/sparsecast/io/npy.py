"""NumPy ``.npy`` volumes: the array ``(nz, ny, nx)`` itself, no spacing or origin."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from ..volume import Volume
from .reading import Read, read_guard

__all__ = ["read_npy", "write_npy"]


def read_npy(path: Path) -> Read:
    """One array from a ``.npy`` file (``allow_pickle=False``), taken as ``(nz, ny, nx)``."""
    arr = read_guard(path, "NumPy .npy", np.load, str(path), allow_pickle=False)
    if not isinstance(arr, np.ndarray):
        raise FileFormatError(f"{str(path)!r}: expected a single array in a .npy file, got {type(arr).__name__}")
    return arr, None, None


def write_npy(volume: Volume, tmp: Path, compress: bool) -> None:
    """The array ``(nz, ny, nx)`` (``compress`` is ignored)."""
    with open(tmp, "wb") as fh:
        np.save(fh, volume.data, allow_pickle=False)
