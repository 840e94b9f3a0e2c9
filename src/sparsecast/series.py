"""Time series of volumes: one grid, many time steps, loaded when a step is asked for.

A :class:`VolumeSeries` is a sequence of :class:`~sparsecast.volume.Volume` with one
shape, dtype and spacing. Steps come from loaders (a file each, or a slice of a
4-D array) and are kept in a small least-recently-used cache, each with the brick
statistics its renders computed, so stepping back and forth costs a TF
classification and a render, not a reload and a pass over the voxels.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Sequence
from typing import overload

import numpy as np

from ._util.checks import as_int, one_of
from .errors import ParameterError, VolumeDataError
from .volume import Volume

__all__ = ["VolumeSeries", "DEFAULT_CACHE_BYTES"]

#: bytes of voxels a series keeps loaded (at least one step)
DEFAULT_CACHE_BYTES = 1 << 30


class VolumeSeries(Sequence):
    """Volumes over time, loaded on demand.

    Parameters
    ----------
    loaders : sequence of callables
        ``loaders[t]()`` returns the volume of step ``t``.
    names : sequence of str
        One label per step (file names, ``t=0`` ...), for messages and output names.
    cache_bytes : int
        Voxel bytes of recently used steps kept in memory (the last one always is).
    name : str
        Label of the series.

    Notes
    -----
    Every step must have the shape, dtype and spacing of step 0; a step that
    differs is an error naming it when it loads.
    """

    def __init__(self, loaders: Sequence[Callable[[], Volume]], names: Sequence[str], *,
                 cache_bytes: int = DEFAULT_CACHE_BYTES, name: str = "series") -> None:
        if len(loaders) == 0:
            raise ParameterError(f"{name}: a series needs at least one time step, got none")
        if len(names) != len(loaders):
            raise ParameterError(f"names: expected {len(loaders)} names, got {len(names)}")
        self._loaders = list(loaders)
        self.names = tuple(str(n) for n in names)
        self.cache_bytes = as_int(cache_bytes, "cache_bytes", lo=0)
        self.name = name
        self._cache: OrderedDict[int, Volume] = OrderedDict()
        self._first: Volume | None = None
        self._range: tuple[float, float] | None = None

    @classmethod
    def from_array(cls, data, spacing=1.0, origin=0.0, *, name: str = "series",
                   cache_bytes: int = DEFAULT_CACHE_BYTES, nonfinite: str = "raise") -> "VolumeSeries":
        """A series from a ``(t, nz, ny, nx)`` array (NumPy, memory-mapped or any array
        that slices lazily): step ``t`` is ``Volume(data[t], nonfinite=nonfinite)``."""
        shape = getattr(data, "shape", None)
        if shape is None or len(shape) != 4 or min(shape) == 0:
            raise VolumeDataError(f"{name!r}: expected a 4-D array (t, nz, ny, nx) with no empty axis, "
                                  f"got shape {shape}")
        one_of(nonfinite, "nonfinite", ("raise", "replace"), expected="'raise' or 'replace'")
        loaders = [lambda t=t: Volume(np.asarray(data[t]), spacing, origin, name=f"{name}[t={t}]",
                                      nonfinite=nonfinite)
                   for t in range(shape[0])]
        return cls(loaders, [f"t={t}" for t in range(shape[0])], cache_bytes=cache_bytes, name=name)

    # -- sequence ---------------------------------------------------------
    def __len__(self) -> int:
        return len(self._loaders)

    @overload
    def __getitem__(self, t: int) -> Volume: ...
    @overload
    def __getitem__(self, t: slice) -> list[Volume]: ...

    def __getitem__(self, t):
        if isinstance(t, slice):
            return [self[i] for i in range(*t.indices(len(self)))]
        t = self.step(t)
        vol = self._cache.get(t)
        if vol is not None:
            self._cache.move_to_end(t)
            return vol
        vol = self._loaders[t]()
        self._check_like_first(t, vol)
        self._cache[t] = vol
        self._evict()
        return vol

    def step(self, t) -> int:
        """The step ``t`` names, in ``0..len-1`` (negative counts from the end); checked."""
        n = len(self)
        try:
            i = int(t)
        except (TypeError, ValueError):
            raise ParameterError(f"time: expected an integer step, got {t!r}") from None
        if i != t or not -n <= i < n:
            raise ParameterError(f"time: expected a step in 0..{n - 1} (or -{n}..-1), got {t!r}")
        return i % n

    def _check_like_first(self, t: int, vol: Volume) -> None:
        if self._first is None:
            self._first = vol
            return
        f = self._first
        for what, a, b in (("shape", vol.shape, f.shape), ("dtype", vol.dtype, f.dtype)):
            if a != b:
                raise VolumeDataError(f"{self.names[t]}: {what} {a} differs from the first step's {b}; "
                                      f"expected every step of {self.name} on one grid")
        if not np.allclose(vol.spacing, f.spacing):
            raise VolumeDataError(f"{self.names[t]}: spacing {tuple(vol.spacing)} differs from the first step's "
                                  f"{tuple(f.spacing)}; expected every step of {self.name} on one grid")

    def _evict(self) -> None:
        held = sum(v.nbytes for v in self._cache.values())
        while len(self._cache) > 1 and held > self.cache_bytes:
            _, old = self._cache.popitem(last=False)
            held -= old.nbytes

    # -- whole-series facts -----------------------------------------------
    @property
    def value_range(self) -> tuple[float, float]:
        """Min and max over every step (one pass over the steps, then cached): the
        range a TF spans so that colours mean the same at every time."""
        if self._range is None:
            lo, hi = np.inf, -np.inf
            for t in range(len(self)):
                a, b = self[t].value_range
                lo, hi = min(lo, a), max(hi, b)
            self._range = (float(lo), float(hi))
        return self._range

    def __repr__(self) -> str:
        return f"VolumeSeries(name={self.name!r}, steps={len(self)}, loaded={sorted(self._cache)})"
