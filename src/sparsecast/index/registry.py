"""Name -> index class registry behind ``build_index`` and ``available_indices``.

Build options are checked here, against the index class's ``__init__`` signature, so
that a misspelt option is one line naming the options the index takes, not a
``TypeError`` from inside the class.
"""

from __future__ import annotations

import difflib
import inspect
import time
from typing import Any

from .._util.checks import fail
from ..errors import ParameterError
from ..kernels.parallel import parallel_section
from .auto import AUTO, choose_index
from .base import SpatialIndex
from .warm import warm_build

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


#: ``render()`` parameters, with the CLI option that sets each: an index build option
#: of the same name could never reach the index (``render(index=..., **options)``).
#: tests/index/test_options.py checks this against render()'s signature.
RENDER_PARAMETERS: dict[str, str] = {
    "volume": "the FILE argument", "tf": "--tf", "camera": "--azimuth/--elevation/--projection/--zoom",
    "width": "--size", "height": "--size", "dt": "--dt", "index": "--index", "ert": "--ert",
    "shading": "--shade", "background": "--background", "clip_box": "render(clip_box=...)",
    "clip_open": "render(clip_open=...)", "clip_planes": "render(clip_planes=...)", "clip_cap": "--clip-cap",
    "initial": "render(initial=...)", "rect": "render(rect=...)", "max_samples": "render(max_samples=...)",
    "iso": "--iso", "iso_colors": "render(iso_colors=...)",
    "client": "--scheduler", "pieces": "--pieces", "cross_termination": "render(cross_termination=...)",
    "timeout": "render(timeout=...)",
}
#: render() parameters that an index may take as a build option too: ``render(mode=...)``
#: passes the BIH's build modes (``ess``, ``single-sample``, ``multi-sample``) on to it
SHARED_WITH_INDICES: dict[str, str] = {"mode": "render(mode='dvr' | 'iso' | 'iso+dvr')"}


def index_options(name: str) -> tuple[str, ...] | None:
    """Build options the named index takes (keyword parameters of its class).

    Follows ``**options`` pass-through to base classes (the hybrids take the k-d
    tree's options). ``None`` when the class accepts arbitrary keywords.

    Parameters
    ----------
    name : str
        One of :func:`available_indices`.
    """
    cls = _index_class(name)
    found: list[str] = []
    for klass in cls.__mro__:
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        open_ended = False
        for i, p in enumerate(inspect.signature(init).parameters.values()):
            if i < 3 and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
                continue  # self, volume, tf
            if p.kind is p.VAR_KEYWORD:
                open_ended = True
            elif p.kind is not p.VAR_POSITIONAL and p.name not in found:
                found.append(p.name)
        if not open_ended:
            return tuple(found)
    return None


def indices_taking(option: str) -> list[str]:
    """Names of the indices whose build options include ``option`` (e.g. ``"cell"``)."""
    return [n for n in available_indices() if option in (index_options(n) or ())]


def check_index_options(name: str, options: dict[str, Any]) -> None:
    """Raise :class:`ParameterError` for a build option ``name`` does not take.

    The message names the option, the options the index takes (and a close match),
    and for ``cell`` the indices that take it; a ``render()`` parameter names the
    option that sets it instead.
    """
    if name == AUTO and options:
        msg = (f"index 'auto': build options ({', '.join(options)}) need a named index; "
               f"choose one with --index NAME:KEY=VALUE (indices: {', '.join(available_indices())})")
        if "cell" in options:
            msg += f"; cell (--cell) applies to: {', '.join(indices_taking('cell'))}"
        raise ParameterError(msg)
    for key in options:
        if key in RENDER_PARAMETERS:
            raise ParameterError(
                f"index {name!r}: {key!r} is a render parameter, not a build option of the index; "
                f"set it with {RENDER_PARAMETERS[key]}"
            )
    accepted = () if name == AUTO else index_options(name)
    if accepted is None:
        return
    for key in options:
        if key in accepted:
            continue
        takes = f"options: {', '.join(accepted)}" if accepted else "no build options"
        msg = f"index {name!r}: unknown option {key!r}; {name} takes {takes}"
        near = difflib.get_close_matches(key, accepted, n=1)
        if near:
            msg += f" (did you mean {near[0]!r}?)"
        if key == "cell":
            msg += f"; cell (--cell) applies to: {', '.join(indices_taking('cell'))}"
        raise ParameterError(msg)


def index_class(name: str) -> type[SpatialIndex]:
    """The class registered under ``name`` (:class:`ParameterError` for an unknown name)."""
    return _index_class(name)


def _index_class(name: str) -> type[SpatialIndex]:
    cls = _INDICES.get(name)
    if cls is None:
        raise ParameterError(f"index: unknown index {name!r}; expected one of: {', '.join(available_indices())}")
    return cls


def build_index(volume, tf, name: str = "naive", **options) -> SpatialIndex:
    """Build the named index for ``volume`` classified by ``tf``.

    Parameters
    ----------
    volume : Volume
    tf : TransferFunction
    name : str
        One of :func:`available_indices`, or ``"auto"``: chosen from the volume's
        brick occupancy under ``tf`` (see :mod:`sparsecast.index.auto`); the choice
        and its reason are kept in the index's ``auto`` attribute.
    **options
        Passed to the index class (e.g. ``cell=8``); :func:`index_options` lists
        what each index takes.

    Returns
    -------
    SpatialIndex
        Its ``build_ms`` excludes first-use kernel compilation, which is in
        ``compile_ms`` (0 once this index and dtype were built in the process).

    Raises
    ------
    ParameterError
        An unknown index, or an option it does not take.
    """
    check_index_options(name, options)
    auto = None
    if name == AUTO:
        name, auto = choose_index(volume, tf, names=available_indices())
    cls = _index_class(name)
    with parallel_section():  # build kernels use prange (see kernels.parallel)
        # First use in this process: compile (or load) the build kernels on a tiny
        # volume of this dtype, so that build_ms is the build's time, not Numba's.
        compile_ms = warm_build(cls, volume, tf, options)
    t0 = time.perf_counter()
    try:
        with parallel_section():
            idx = cls(volume, tf, **options)
    except TypeError as exc:  # an index that takes **options and forwards them elsewhere
        if "unexpected keyword" not in str(exc):
            raise
        raise ParameterError(f"index {name!r}: {exc}") from None
    if not idx.build_phases:
        idx.build_phases = {"build": (time.perf_counter() - t0) * 1e3}
    idx.compile_ms = compile_ms
    if auto is not None:
        idx.auto = auto  # why "auto" chose it: render() reports it in stats["auto"]
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
        An option without ``=``, an unknown index name, or an option the index
        does not take (see :func:`check_index_options`).
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
    if name not in available_indices() and name != AUTO:
        raise ParameterError(f"method {spec!r}: unknown index {name!r}; expected one of {', '.join(available_indices())}")
    check_index_options(name, options)
    return name, options
