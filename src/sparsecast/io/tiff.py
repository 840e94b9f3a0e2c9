"""TIFF volumes: a multi-page stack (``.tif``, ``.tiff``) or a directory of 2-D slices, through tifffile."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from ..volume import Volume
from .budget import check_declared
from .files import file_size, require_regular_file
from .names import natural_key
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
    arr, axes = _read_series(path)
    return _tiff_to_3d(np.asarray(arr), axes, path), None, None


def _read_series(path: Path) -> tuple[np.ndarray, str]:
    """The first series of a TIFF file and its axes, after its declared size is checked."""
    import tifffile

    require_regular_file(path, "TIFF file")

    def _read():
        with tifffile.TiffFile(str(path)) as tf:
            if not tf.series:
                raise FileFormatError(f"{str(path)!r}: TIFF file holds no image series")
            series = tf.series[0]
            _check_series(path, series)
            return series.asarray(), series.axes

    return read_guard(path, "TIFF", _read)


def _check_series(path: Path, series) -> None:
    """A series' shape against its pages' stored bytes (uncompressed) and the memory limit.

    A shaped series (tifffile's JSON description) can claim any shape for one small
    page, and a page any size for a few stored bytes.
    """
    declared = math.prod(int(n) for n in series.shape) * series.dtype.itemsize
    what = f"TIFF series (shape {tuple(series.shape)}, {series.dtype})"
    size = file_size(path)
    stored, compressed = 0, False
    for page in series.pages:
        if page is None:
            continue
        key = getattr(page, "keyframe", None) or page
        compressed = compressed or int(getattr(key, "compression", 1)) != 1
        for off, count in zip(page.dataoffsets, page.databytecounts):
            stored += max(0, min(int(count), size - int(off)))  # what the file really holds
    check_declared(path, declared, what, available=None if compressed else stored)



def read_tiff_dir(path: Path) -> Read:
    """A directory of 2-D grayscale TIFF slices (same shape and dtype), stacked along z
    in natural name order (``s2.tif`` before ``s10.tif``)."""
    files = sorted(
        (f for f in path.iterdir() if f.is_file() and f.suffix.lower() in TIFF_SUFFIXES),
        key=natural_key,
    )
    if not files:
        raise FileFormatError(
            f"{str(path)!r}: directory holds no .tif/.tiff slices; a directory is read as a stack "
            f"of 2-D TIFF slices"
        )
    slices = []
    for f in files:
        img, _ = _read_series(f)
        img = np.asarray(img)
        if img.ndim != 2:
            raise FileFormatError(f"{str(f)!r}: slice of shape {img.shape}; expected a 2-D grayscale image")
        if slices and (img.shape != slices[0].shape or img.dtype != slices[0].dtype):
            raise FileFormatError(
                f"{str(f)!r}: slice is {img.shape} {img.dtype}, expected {slices[0].shape} "
                f"{slices[0].dtype} like {files[0].name!r}"
            )
        if not slices:
            check_declared(path, img.nbytes * len(files),
                           f"stack of {len(files)} slices of {img.shape} {img.dtype}")
        slices.append(img)
    return np.stack(slices, axis=0), None, None


def write_tiff(volume: Volume, tmp: Path, compress: bool) -> None:
    """One grayscale page per z slice; no spacing (``compress`` is ignored)."""
    import tifffile

    tifffile.imwrite(str(tmp), volume.data, photometric="minisblack")
