"""Reading time series: a folder or glob of volume files, a list of paths, a 4-D array,
``.npy`` or NIfTI, or a Zarr / OME-Zarr store with a time axis."""

from __future__ import annotations

import glob
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, ParameterError
from ..series import DEFAULT_CACHE_BYTES, VolumeSeries
from .files import require_regular_file
from .formats import READ_SUFFIXES
from .names import natural_key, suffix_of
from .nifti import nifti_steps, read_nifti
from .sources import is_zarr_dir, open_source, time_steps
from .volumes import load_volume

__all__ = ["load_series"]



def load_series(source: Any, *, cache_bytes: int = DEFAULT_CACHE_BYTES, spacing=None, origin=None,
                **load_options: Any) -> VolumeSeries:
    """A :class:`~sparsecast.series.VolumeSeries` from files or an array.

    Parameters
    ----------
    source : path, str, sequence of paths, or array
        A directory (every volume file in it, in natural name order: ``t2`` before
        ``t10``), a glob pattern (``"run/step_*.nrrd"``), a list of files (in the
        given order), a ``(t, nz, ny, nx)`` array, a 4-D ``.npy`` file (memory-mapped:
        a step is read when it is asked for), a 4-D NIfTI image ``(x, y, z, t)`` (one
        volume read per step), or a Zarr store holding a 4-D ``(t, nz, ny, nx)`` array or
        an OME-Zarr image with a ``t`` axis (one step read per step, lazily as a
        :class:`~sparsecast.storage.BrickedVolume` when a step exceeds the memory budget;
        ``level=`` picks the OME-Zarr level).
    cache_bytes : int
        Voxel bytes of recent steps kept in memory.
    spacing, origin, **load_options
        Passed to :func:`~sparsecast.io.load_volume` for every file (spacing and
        origin also for arrays).

    Raises
    ------
    FileFormatError
        A folder or pattern without volume files, or a ``.npy`` that is not 4-D.
    """
    if isinstance(source, np.ndarray) or (hasattr(source, "shape") and hasattr(source, "__getitem__")
                                          and not isinstance(source, (str, os.PathLike))):
        return VolumeSeries.from_array(source, 1.0 if spacing is None else spacing,
                                       0.0 if origin is None else origin, cache_bytes=cache_bytes,
                                       nonfinite=load_options.get("nonfinite", "raise"))
    if isinstance(source, (list, tuple)):
        files = [Path(p) for p in source]
        label = f"{len(files)} files"
    else:
        text = os.fspath(source)
        path = Path(text)
        if path.suffix.lower() == ".npy" and path.is_file():
            return _npy_series(path, spacing, origin, cache_bytes, load_options.get("nonfinite", "raise"))
        if is_zarr_dir(path):
            return _zarr_series(path, spacing, origin, cache_bytes, **load_options)
        if suffix_of(path) in (".nii", ".nii.gz") and path.is_file() and nifti_steps(path) is not None:
            return _nifti_series(path, spacing, origin, cache_bytes, **load_options)
        if path.is_dir():
            files = sorted((f for f in path.iterdir() if f.is_file() and suffix_of(f) in READ_SUFFIXES),
                           key=natural_key)
            label = text
            if not files:
                raise FileFormatError(f"{text!r}: directory holds no volume files ({', '.join(READ_SUFFIXES)}); "
                                      "expected one file per time step")
        elif glob.has_magic(text):
            files = sorted((Path(f) for f in glob.glob(text)), key=natural_key)
            label = text
            if not files:
                raise FileFormatError(f"{text!r}: the pattern matches no files; expected one file per time step")
        else:
            raise FileFormatError(f"{text!r}: expected a directory, a glob pattern, a list of files, a 4-D "
                                  ".npy or NIfTI file, or a Zarr store with a time axis, for a time series")
    kw = dict(load_options)
    if spacing is not None:
        kw["spacing"] = spacing
    if origin is not None:
        kw["origin"] = origin
    loaders = [lambda f=f: load_volume(f, **kw) for f in files]
    return VolumeSeries(loaders, [f.name for f in files], cache_bytes=cache_bytes, name=label)


def _npy_series(path: Path, spacing, origin, cache_bytes: int, nonfinite: str = "raise") -> VolumeSeries:
    require_regular_file(path, ".npy file")
    try:
        arr = np.load(path, mmap_mode="r", allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise FileFormatError(f"{str(path)!r}: not a readable .npy file ({exc})") from None
    if arr.ndim != 4:
        raise FileFormatError(f"{str(path)!r}: {arr.ndim}-D array of shape {arr.shape}; expected a 4-D "
                              "(t, nz, ny, nx) array for a time series")
    if spacing is None:
        spacing = 1.0
    if origin is None:
        origin = 0.0
    series = VolumeSeries.from_array(arr, spacing, origin, name=path.name, cache_bytes=cache_bytes,
                                     nonfinite=nonfinite)
    return series


def _zarr_series(path: Path, spacing, origin, cache_bytes: int, *, level=None, missing_chunks: str = "auto",
                 nonfinite: str = "raise", **rest: Any) -> VolumeSeries:
    """A series over the ``t`` axis of a Zarr store: step ``t`` is opened on demand."""
    from ..storage import BrickedVolume
    from ..volume import Volume
    from .budget import memory_limit

    rest = {k: v for k, v in rest.items() if v is not None}
    if rest:
        raise ParameterError(f"{', '.join(sorted(rest))}: do not apply to a Zarr time series")
    n = time_steps(path, level=level)

    def step(t: int) -> Volume:
        src = open_source(path, level=level, missing_chunks=missing_chunks, time=t)
        sp = src.spacing if spacing is None else spacing
        org = src.origin if origin is None else origin
        label = f"{src.name}[t={t}]"
        if src.array.nbytes > memory_limit():  # a step larger than the budget stays on disk
            return BrickedVolume(src.array, sp, org, name=label, nonfinite=nonfinite)
        return Volume(np.asarray(src.array[:, :, :]), sp, org, name=label, nonfinite=nonfinite)

    return VolumeSeries([lambda t=t: step(t) for t in range(n)], [f"t={t}" for t in range(n)],
                        cache_bytes=cache_bytes, name=path.name)


def _nifti_series(path: Path, spacing, origin, cache_bytes: int, *, nonfinite: str = "raise",
                  orientation=None, **rest: Any) -> VolumeSeries:
    """A series over the fourth axis of a NIfTI image: step ``t`` is read on demand."""
    from ..volume import Volume

    rest = {k: v for k, v in rest.items() if v is not None}
    if rest:
        raise ParameterError(f"{', '.join(sorted(rest))}: do not apply to a NIfTI time series")
    n = int(nifti_steps(path))

    def step(t: int) -> Volume:
        read = read_nifti(path, step=t)
        sp = spacing if spacing is not None else (read.spacing if read.spacing is not None else 1.0)
        org = origin if origin is not None else (read.origin if read.origin is not None else 0.0)
        return Volume(read.data, sp, org, name=f"{path.name}[t={t}]", nonfinite=nonfinite,
                      orientation=orientation if orientation is not None else read.orientation)

    return VolumeSeries([lambda t=t: step(t) for t in range(n)], [f"t={t}" for t in range(n)],
                        cache_bytes=cache_bytes, name=path.name)
