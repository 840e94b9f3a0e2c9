"""The volume, transfer function and orbit frame that a command's FILE, ``--dims``/
``--dtype``/``--spacing``/``--orientation``, ``--tf``/``--tf-range``/``--threshold`` and
``--up``/``--view`` options name (render, info, view)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

from ..errors import ParameterError
from .parse import parse_dims, parse_pair, parse_spacing

__all__ = ["load_input", "make_tf", "nonfinite_policy", "orbit_frame", "orbit_angles"]


def nonfinite_policy(value: str) -> str:
    """``--nonfinite``'s value, checked under the option's own name (``raise`` or ``replace``)."""
    from .._util.checks import one_of

    return one_of(value, "--nonfinite", ("raise", "replace"), expected="'raise' or 'replace'")


def load_input(file: Optional[Path], dims: Optional[str], dtype: Optional[str], spacing: Optional[str],
               allow_outside: bool = False, orientation: Optional[str] = None, *, lazy: Optional[bool] = None,
               memory_limit: Optional[str] = None, level: Optional[str] = None,
               nonfinite: Optional[str] = None):
    """The volume in ``file`` (raw layout and spacing from the options), or the built-in
    demo when no file is given.

    ``allow_outside`` (``--allow-outside-data``) lets a detached NRRD header name a data
    file outside its folder; the viewer never passes it (it serves what it reads).
    ``orientation`` (``--orientation``) sets the axis codes, e.g. for a file that lost them.
    ``lazy``, ``memory_limit`` and ``level`` (``--lazy``, ``--memory-limit``, ``--level``) are
    :func:`~sparsecast.io.load_volume`'s: bricks read on demand, their budget, an OME-Zarr level.
    ``nonfinite`` (``--nonfinite``): ``"raise"`` (the default) or ``"replace"`` NaN/Inf voxels.
    """
    from ..datasets import demo_volume
    from ..io import load_volume

    if file is None:
        given = [opt for opt, v in (("--dims", dims), ("--dtype", dtype), ("--spacing", spacing),
                                    ("--orientation", orientation), ("--lazy", lazy), ("--memory-limit", memory_limit),
                                    ("--level", level), ("--nonfinite", nonfinite)) if v]
        if given:  # silently ignoring them would render the demo as if they applied
            raise ParameterError(
                f"{', '.join(given)}: {'applies' if len(given) == 1 else 'apply'} only to a volume FILE; none was "
                f"given (the built-in demo has its own layout)"
            )
        return demo_volume()
    kw = {}
    if dims:
        kw["dims"] = parse_dims(dims)
    if dtype:
        kw["dtype"] = dtype
    if spacing:
        kw["spacing"] = parse_spacing(spacing)
    if orientation:
        from ..axes import check_orientation

        kw["orientation"] = check_orientation(orientation, "--orientation")
    if lazy is not None:
        kw["lazy"] = lazy
    if memory_limit:
        kw["memory_limit"] = memory_limit
    if level is not None:
        kw["level"] = int(level) if level.isdigit() else level
    if nonfinite is not None:
        kw["nonfinite"] = nonfinite_policy(nonfinite)
    return load_volume(file, allow_outside=allow_outside, **kw)


def orbit_frame(vol, file: Optional[Path], up: Optional[str], view: Optional[str]) -> dict:
    """``Camera.orbit``'s ``up=`` / ``view=`` for ``--up`` / ``--view``: a volume with an
    anatomical orientation is seen from the front (``view="anterior"``) unless ``--up``
    says otherwise, so a head is not shown from behind; others orbit about +z.

    Raises
    ------
    ParameterError
        ``--up`` and ``--view`` both given, a bad axis or view name, or ``--view`` for a
        volume without orientation (naming the file and what is missing).
    """
    from ..axes import VIEWS, axis_vector

    if up is not None and view is not None:
        raise ParameterError(f"--up {up}, --view {view}: a view sets the up direction itself; give one of them")
    if up is not None:
        axis_vector(up, "--up")
        return {"up": up}
    if view is not None:
        if view.lower() not in VIEWS:
            raise ParameterError(f"--view: expected one of {', '.join(VIEWS)}, got {view!r}")
        if vol.orientation is None:
            raise ParameterError(
                f"--view {view}: {repr(str(file)) if file else 'the built-in demo'} has no anatomical orientation "
                f"(no NRRD 'space' field such as left-posterior-superior, no NIfTI sform/qform code); pass "
                f"--orientation with the axis codes of +i, +j, +k (e.g. RAS or LPS) if you know them, or "
                f"use --up / --azimuth / --elevation"
            )
        return {"view": view.lower()}
    return {"view": "anterior"} if vol.orientation is not None else {}


def make_tf(spec: str, vol, tf_range: Optional[str], threshold, default_range=None):
    """A preset over the volume's range (or ``tf_range``), a TF ``.json`` file
    (re-ranged only when ``tf_range`` is given; a label file is used as it is), or a
    label TF: ``labels`` (every id the volume holds but 0, distinct colours) or
    ``labels:1,4,7`` (those ids). ``default_range`` replaces the volume's range as the
    presets' default (a time series spans the range of all its steps). ``threshold``:
    ``--threshold`` as given (a fraction, or ``auto``: :func:`threshold_value`)."""
    from ..transfer import TransferFunction

    if spec.lower() == "labels" or spec.lower().startswith("labels:"):
        return label_tf(spec, vol)
    value_range = preset_range(vol, tf_range, default_range)
    if spec.lower().endswith(".json"):
        tf = TransferFunction.load(spec)
        return tf.with_range(value_range) if tf_range else tf
    return TransferFunction.preset(spec, value_range, threshold=threshold_value(threshold, vol, value_range))


def preset_range(vol, tf_range: Optional[str], default_range=None) -> tuple[float, float]:
    """The range a preset of :func:`make_tf` spans: ``--tf-range``, else ``default_range``,
    else the volume's."""
    return parse_pair(tf_range, "--tf-range") if tf_range else (default_range or vol.value_range)


def threshold_value(threshold, vol, value_range) -> float:
    """``--threshold``: a fraction as given, or for ``auto`` the volume's
    (:func:`sparsecast.auto_threshold` over the TF's ``value_range``)."""
    from ..threshold import auto_threshold

    if isinstance(threshold, str):
        text = threshold.strip()
        if text.lower() == "auto":
            return auto_threshold(vol, value_range)
        try:
            return float(text)
        except ValueError:
            raise ParameterError(f"--threshold: expected a fraction in [0, 1) or 'auto', got {threshold!r}") from None
    return float(threshold)


def smoothed_labels(tfn, spec: str, smooth: bool):
    """``--smooth-labels``: the label TF ``tfn`` (from ``--tf spec``) with smooth boundaries."""
    if not smooth:
        return tfn
    if tfn.sampling == "trilinear":
        raise ParameterError(f"--smooth-labels: applies to label TFs (--tf labels, labels:ID,... or a "
                             f"sparsecast-labels .json); got --tf {spec}, a {tfn.name!r} TF of a scalar field")
    return tfn.smoothed()


def label_tf(spec: str, vol):
    """``--tf labels[:ID,ID,...]``: distinct colours for the ids of a label volume."""
    from ..transfer import TransferFunction

    ids = vol.label_ids()
    if ids is None:
        raise ParameterError(
            f"--tf {spec}: {vol.name} is not a label volume (expected integer ids, at most 4096 distinct "
            f"values); its values span [{vol.value_range[0]:g}, {vol.value_range[1]:g}]"
        )
    _, _, listed = spec.partition(":")
    if listed.strip():
        try:
            shown = [int(x, 10) for x in listed.split(",") if x.strip()]
        except ValueError:
            raise ParameterError(f"--tf {spec}: expected labels:ID,ID,... with integer ids") from None
        missing = sorted(set(shown) - set(ids.tolist()))
        if missing:
            raise ParameterError(
                f"--tf {spec}: id(s) {', '.join(map(str, missing))} do not occur in {vol.name}; it holds "
                f"{_id_list(ids)}"
            )
    else:
        shown = [int(i) for i in ids if i != 0] or [int(ids[0])]
    return TransferFunction.labels(shown, name=spec)


def _id_list(ids, limit: int = 20) -> str:
    text = ", ".join(str(int(i)) for i in ids[:limit])
    return text + (f", ... ({len(ids)} ids)" if len(ids) > limit else "")


def orbit_angles(frame: dict, azimuth: Optional[float], elevation: Optional[float]) -> tuple[float, float]:
    """The orbit angles: as given, else 0, 0 from a named view (the view itself) and the
    three-quarter 30, 20 otherwise."""
    az0, el0 = (0.0, 0.0) if "view" in frame else (30.0, 20.0)
    return (az0 if azimuth is None else azimuth), (el0 if elevation is None else elevation)
