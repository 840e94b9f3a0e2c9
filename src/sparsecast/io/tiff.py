"""TIFF volumes: a multi-page stack (``.tif``, ``.tiff``) or a directory of 2-D slices, through tifffile."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from ..volume import Volume
from .reading import Read, read_guard

__all__ = ["TIFF_SUFFIXES", "read_tiff", "read_tiff_dir", "write_tiff"]

#: the suffixes of TIFF files (also of the slices in a directory)
TIFF_SUFFIXES = (".tif", ".tiff")


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


def read_tiff(path: Path) -> Read:
    """The first image series of a TIFF: a multi-page grayscale stack or a 3-D array."""
    import tifffile

    def _read():
        with tifffile.TiffFile(str(path)) as tf:
            if not tf.series:
                raise FileFormatError(f"{str(path)!r}: TIFF file holds no image series")
            series = tf.series[0]
            return series.asarray(), series.axes

    arr, axes = read_guard(path, "TIFF", _read)
    return _tiff_to_3d(np.asarray(arr), axes, path), None, None


def _natural_key(p: Path):
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", p.name)]


def read_tiff_dir(path: Path) -> Read:
    """A directory of 2-D grayscale TIFF slices (same shape and dtype), stacked along z
    in natural name order (``s2.tif`` before ``s10.tif``)."""
    import tifffile

    files = sorted(
        (f for f in path.iterdir() if f.is_file() and f.suffix.lower() in TIFF_SUFFIXES),
        key=_natural_key,
    )
    if not files:
        raise FileFormatError(
            f"{str(path)!r}: directory holds no .tif/.tiff slices; a directory is read as a stack "
            f"of 2-D TIFF slices"
        )
    slices = []
    for f in files:
        img = np.asarray(read_guard(f, "TIFF", tifffile.imread, str(f)))
        if img.ndim != 2:
            raise FileFormatError(f"{str(f)!r}: slice of shape {img.shape}; expected a 2-D grayscale image")
        if slices and (img.shape != slices[0].shape or img.dtype != slices[0].dtype):
            raise FileFormatError(
                f"{str(f)!r}: slice is {img.shape} {img.dtype}, expected {slices[0].shape} "
                f"{slices[0].dtype} like {files[0].name!r}"
            )
        slices.append(img)
    return np.stack(slices, axis=0), None, None


def write_tiff(volume: Volume, tmp: Path, compress: bool) -> None:
    """One grayscale page per z slice; no spacing (``compress`` is ignored)."""
    import tifffile

    tifffile.imwrite(str(tmp), volume.data, photometric="minisblack")
