"""First-use compilation of an index's build kernels, kept out of its build time.

Numba compiles (or loads from the on-disk cache) a kernel the first time a process
calls it with new argument types: tens of seconds on a cold cache, which used to land
in ``build_ms``. :func:`warm_build` builds the index once per process on a tiny volume
of the real volume's dtype, classified by the real TF (the same argument types, so the
same specialisations), and returns the time that took: what the first real build
would otherwise have spent compiling.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..transfer import TransferFunction
from ..volume import Volume
from .base import SpatialIndex

__all__ = ["warm_build", "tiny_volume", "TINY"]

#: edge of the warm-up volume: three 8^3 bricks per axis, so the k-d trees split,
#: grids have runs of cells and the BIH several leaves
TINY = 25

# (index class, dtype, options) already built once in this process
_WARM: set[tuple] = set()


def tiny_volume(dtype: np.dtype, value_range: tuple[float, float], size: int = TINY,
                labels: tuple[int, ...] | None = None) -> Volume:
    """A small deterministic volume of ``dtype`` spanning ``value_range``: two blobs in empty space.

    With ``labels``, a label volume instead: the blobs hold the first two of these ids
    (the TF's visible ones, so label TFs find bricks to keep) on a background of the
    lowest value, few distinct values as label volumes have.

    Parameters
    ----------
    dtype : numpy dtype
        One of :data:`sparsecast.volume.SUPPORTED_DTYPES`.
    value_range : (lo, hi)
        Values go from ``lo`` (the empty background) to ``hi`` (the blob centres),
        clipped to what ``dtype`` holds.
    size : int
        Voxels per edge.
    labels : tuple of int, optional
        Ids to fill the blobs with (a label volume).

    Returns
    -------
    Volume
        Shape ``(size, size, size)``.
    """
    dtype = np.dtype(dtype)
    g = np.linspace(0.0, 1.0, size)
    z, y, x = np.meshgrid(g, g, g, indexing="ij")
    field = np.zeros((size, size, size))
    for cx, cy, cz, s in ((0.3, 0.35, 0.4, 0.12), (0.7, 0.6, 0.65, 0.08)):
        field = np.maximum(field, np.exp(-((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) / (2 * s * s)))
    field[field < 0.05] = 0.0  # exact empty space, as the indices skip it
    lo, hi = value_range
    values = lo + (hi - lo) * field
    if labels:
        ids = [float(i) for i in labels[:2]] * (2 // min(len(labels), 2))
        values = np.full_like(field, lo)
        values[(field > 0) & (x < 0.5)] = ids[0]
        values[(field > 0) & (x >= 0.5)] = ids[1]
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        values = np.clip(np.rint(values), info.min, info.max)
    return Volume(values.astype(dtype), name=f"warm-up {dtype}")


def warm_build(cls: type[SpatialIndex], volume: Volume, tf: TransferFunction, options: dict[str, Any]) -> float:
    """Build ``cls`` once per process on a tiny volume like ``volume``; milliseconds spent.

    Returns 0 when this index class, dtype and options were warmed already. The
    options are passed as given (they select kernels: ``bih:mode=...``); a
    failure on the tiny volume is left for the real build to report.
    """
    key = (cls, volume.dtype.str, type(tf), repr(sorted(options.items())))
    if key in _WARM:
        return 0.0
    t0 = time.perf_counter()
    try:
        # A label TF (nearest sampling) classifies bricks by their label sets: a tiny
        # label volume of its visible ids runs those kernels too.
        labels = tuple(getattr(tf, "visible", ())) if getattr(tf, "sampling", "trilinear") != "trilinear" else None
        cls(tiny_volume(volume.dtype, tf.value_range, labels=labels), tf, **options)
    except Exception:  # noqa: BLE001 - bad options etc.: the real build raises the user-facing error
        return (time.perf_counter() - t0) * 1e3
    _WARM.add(key)
    return (time.perf_counter() - t0) * 1e3
