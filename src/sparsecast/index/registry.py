"""Name -> index class registry behind ``build_index`` and ``available_indices``."""

from __future__ import annotations

import time
from typing import Any

from .._util.checks import fail
from ..errors import ParameterError
from ..kernels.parallel import parallel_section
from .base import SpatialIndex

_INDICES: dict[str, type[SpatialIndex]] = {}


def register_index(cls: type[SpatialIndex]) -> type[SpatialIndex]:
    """Class decorator: make ``cls`` available under ``cls.name``."""
    if not cls.name:
        raise TypeError(f"{cls.__name__} has no name")
    _INDICES[cls.name] = cls
    return cls


def available_indices() -> list[str]:
    """Names accepted by ``render(index=...)``, ``"naive"`` first."""
    return sorted(_INDICES, key=lambda n: (n != "naive", n))


def build_index(volume, tf, name: str = "naive", **options) -> SpatialIndex:
    """Build the named index for ``volume`` classified by ``tf``.

    Parameters
    ----------
    volume : Volume
    tf : TransferFunction
    name : str
        One of :func:`available_indices`.
    **options
        Passed to the index class (e.g. ``brick_size``).
    """
    cls = _INDICES.get(name)
    if cls is None:
        raise ParameterError(f"index: unknown index {name!r}; expected one of: {', '.join(available_indices())}")
    t0 = time.perf_counter()
    try:
        with parallel_section():  # build kernels use prange (see kernels.parallel)
            idx = cls(volume, tf, **options)
    except TypeError as exc:
        if "unexpected keyword" not in str(exc):
            raise
        raise ParameterError(f"index {name!r}: {exc}") from None
    if not idx.build_phases:
        idx.build_phases = {"build": (time.perf_counter() - t0) * 1e3}
    return idx


_LITERALS = {"none": None, "true": True, "false": False}


def parse_index_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """``"grid-pc:cell=8"`` -> ``("grid-pc", {"cell": 8})``.

    Values are parsed as None/True/False, int, float, or else kept as strings.

    Parameters
    ----------
    spec : str
        An index name (see :func:`sparsecast.available_indices`), optionally followed
        by build options ``:key=value[,key=value]``.

    Returns
    -------
    (str, dict)
        The index name and its build options.

    Raises
    ------
    ParameterError
        An option without ``=``, or an unknown index name.
    """
    name, _, opts = spec.partition(":")
    options: dict[str, Any] = {}
    for item in filter(None, opts.split(",")):
        key, eq, value = item.partition("=")
        if not eq:
            raise fail(f"method {spec!r}", "name:key=value[,key=value]", item)
        if value.lower() in _LITERALS:
            options[key] = _LITERALS[value.lower()]
            continue
        for conv in (int, float):
            try:
                options[key] = conv(value)
                break
            except ValueError:
                continue
        else:
            options[key] = value
    if name not in available_indices():
        raise ParameterError(f"method {spec!r}: unknown index {name!r}; expected one of {', '.join(available_indices())}")
    return name, options
