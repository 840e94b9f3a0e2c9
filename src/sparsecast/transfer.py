"""Transfer functions: piecewise-linear RGBA over a value range, baked to a table.

A :class:`TransferFunction` maps a scalar value ``v`` to straight (not premultiplied)
RGBA. It is defined by control points and baked to a table of ``table_size`` entries
spanning ``value_range``; renderers look values up with linear interpolation between
neighbouring entries (values outside the range clamp to the end entries).

Emptiness queries ("is the opacity zero for every value in ``[lo, hi]``?") are O(1):
a prefix count of entries with non-zero opacity answers them without looking at
voxels, which is what makes rebuilding an empty-space index on a TF change cheap.

Label volumes (segmentations) take a :class:`LabelTransferFunction`
(:meth:`TransferFunction.labels`): one table entry per label id, nearest sampling.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ParameterError, TransferFunctionError
from ._util.atomic import atomic_path
from .tf_schema import check_tf_dict, read_tf_file
from .kernels.parallel import parallel_section
from .kernels.classify import classify_ranges, entry_span, range_is_empty
from .kernels.label_sets import any_visible

__all__ = ["TransferFunction", "LabelTransferFunction", "PRESETS", "LABELS_FORMAT", "MAX_LABEL_SPAN"]

_MIN_TABLE, _MAX_TABLE = 256, 4096
#: baked opacities below this are stored as exactly 0 (far below one 16-bit step)
_ALPHA_FLOOR = 1e-9

# Presets: normalised control points (position in [0, 1] of the value range,
# r, g, b, a). Colour-map presets take their colours from matplotlib and get an
# opacity ramp; these are the hand-made ones.
_HAND_PRESETS: dict[str, list[tuple[float, float, float, float, float]]] = {
    # Grey ramp, fully transparent below 10 % of the range.
    "grayscale": [
        (0.0, 0.0, 0.0, 0.0, 0.0),
        (0.1, 0.1, 0.1, 0.1, 0.0),
        (1.0, 1.0, 1.0, 1.0, 0.6),
    ],
    # CT-like: air transparent, soft tissue faint and reddish, bone bright and opaque.
    "bone": [
        (0.00, 0.00, 0.00, 0.00, 0.00),
        (0.25, 0.55, 0.25, 0.15, 0.00),
        (0.35, 0.85, 0.50, 0.35, 0.05),
        (0.50, 0.90, 0.75, 0.60, 0.10),
        (0.65, 1.00, 0.95, 0.85, 0.60),
        (1.00, 1.00, 1.00, 1.00, 0.90),
    ],
}
_HAND_PRESETS["gray"] = _HAND_PRESETS["grayscale"]
_HAND_PRESETS["ct-bone"] = _HAND_PRESETS["bone"]

#: matplotlib colour maps offered as presets (opacity ramps from ``threshold`` to 1).
_COLORMAP_PRESETS = ("viridis", "magma", "inferno", "plasma", "cividis", "turbo", "hot", "coolwarm")

#: Names accepted by :meth:`TransferFunction.preset`.
PRESETS: tuple[str, ...] = tuple(sorted(_HAND_PRESETS)) + _COLORMAP_PRESETS


class TransferFunction:
    """Piecewise-linear RGBA transfer function.

    Parameters
    ----------
    points : array_like, shape (n, 5)
        Control points ``(value, r, g, b, a)`` with values in data units, sorted by
        value (ties allowed for steps); colours and opacity in ``[0, 1]``. Between
        points the TF is linear; below the first / above the last it is constant.
    value_range : (float, float), optional
        Data range covered by the baked table. Defaults to the first and last
        control point values.
    table_size : int, optional
        Number of table entries, 256 to 4096 (default 1024).
    unit_distance : float, optional
        World distance over which a sample's opacity ``a`` applies unchanged; for a
        step ``dt`` the renderer uses ``1 - (1 - a) ** (dt / unit_distance)``. The
        default ``None`` means one voxel (the volume's smallest spacing).
    name : str, optional
        Label for messages and benchmark records.

    Examples
    --------
    >>> tf = TransferFunction([(0, 0, 0, 0, 0), (1, 1, 1, 1, 1)], table_size=256)
    >>> tf.is_empty(-5.0, 0.0)
    True
    >>> tf.is_empty(0.0, 0.5)
    False
    """

    #: how renderers sample the volume for this TF: ``"trilinear"`` (scalar fields) or
    #: ``"nearest"`` (label ids, see :class:`LabelTransferFunction`)
    sampling = "trilinear"

    def __init__(
        self,
        points,
        value_range: tuple[float, float] | None = None,
        *,
        table_size: int = 1024,
        unit_distance: float | None = None,
        name: str = "custom",
    ) -> None:
        pts = np.array(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 5 or pts.shape[0] < 1:
            raise TransferFunctionError(
                f"points: expected an (n, 5) array of (value, r, g, b, a) with n >= 1, got shape {pts.shape}"
            )
        if not np.all(np.isfinite(pts)):
            raise TransferFunctionError("points: expected finite numbers, found NaN or Inf")
        if np.any(np.diff(pts[:, 0]) < 0):
            raise TransferFunctionError(f"points: values must be sorted ascending, got {pts[:, 0].tolist()}")
        if np.any(pts[:, 1:] < 0) or np.any(pts[:, 1:] > 1):
            raise TransferFunctionError("points: r, g, b, a must lie in [0, 1]")
        if value_range is None:
            value_range = (pts[0, 0], pts[-1, 0])
        lo, hi = (float(v) for v in value_range)
        if not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
            raise TransferFunctionError(f"value_range: expected finite lo <= hi, got ({lo}, {hi})")
        if hi == lo:
            # A constant volume still needs a non-degenerate table.
            hi = lo + 1.0
        table_size = int(table_size)
        if not _MIN_TABLE <= table_size <= _MAX_TABLE:
            raise ParameterError(f"table_size: expected {_MIN_TABLE}..{_MAX_TABLE}, got {table_size}")
        scale = (table_size - 1) / (hi - lo)
        if not (np.isfinite(scale) and scale > 0):
            # Spans below ~1e-305 (or beyond the float range) cannot be mapped to table entries.
            raise TransferFunctionError(
                f"value_range: span {hi - lo:g} of ({lo:g}, {hi:g}) is too small or too large "
                "to map onto a table; expected a span between about 1e-300 and 1e300"
            )
        if unit_distance is not None and not (np.isfinite(unit_distance) and unit_distance > 0):
            raise ParameterError(f"unit_distance: expected a positive number or None, got {unit_distance}")

        self.points = pts
        self.points.flags.writeable = False
        self.value_range = (lo, hi)
        self.table_size = table_size
        self.unit_distance = None if unit_distance is None else float(unit_distance)
        self.name = name
        self.table = self._bake()
        self.table.flags.writeable = False
        # prefix[i] = number of entries among table[:i] with non-zero opacity.
        self._prefix = _nonzero_prefix(self.table)

    # -- construction -----------------------------------------------------
    @classmethod
    def preset(
        cls,
        name: str,
        value_range: tuple[float, float] = (0.0, 1.0),
        *,
        threshold: float = 0.1,
        max_opacity: float = 0.8,
        table_size: int = 1024,
        unit_distance: float | None = None,
    ) -> "TransferFunction":
        """A named preset stretched over ``value_range``.

        Parameters
        ----------
        name : str
            One of :data:`PRESETS`: ``grayscale``/``gray``, ``bone``/``ct-bone``, or a
            matplotlib colour map (``viridis``, ``magma``, ``inferno``, ``plasma``,
            ``cividis``, ``turbo``, ``hot``, ``coolwarm``).
        value_range : (float, float)
            Data values mapped to the ends of the preset (e.g. ``volume.value_range``).
        threshold : float
            Colour-map presets only: fraction of the range below which the TF is fully
            transparent (this is what makes space empty).
        max_opacity : float
            Colour-map presets only: opacity at the top of the range.
        """
        key = name.lower()
        try:
            lo, hi = (float(v) for v in value_range)
        except (TypeError, ValueError):
            raise TransferFunctionError(
                f"value_range: expected two numbers (lo, hi), got {value_range!r}"
            ) from None
        if not (np.isfinite(lo) and np.isfinite(hi)) or hi < lo:
            raise TransferFunctionError(f"value_range: expected finite lo <= hi, got ({lo}, {hi})")
        if key in _HAND_PRESETS:
            norm = np.array(_HAND_PRESETS[key], dtype=np.float64)
        elif key in _COLORMAP_PRESETS:
            if not (0.0 <= threshold < 1.0):
                raise ParameterError(f"threshold: expected a fraction in [0, 1), got {threshold}")
            if not (0.0 < max_opacity <= 1.0):
                raise ParameterError(f"max_opacity: expected a value in (0, 1], got {max_opacity}")
            norm = _colormap_points(key, threshold, max_opacity)
        else:
            raise TransferFunctionError(f"unknown preset {name!r}; expected one of: {', '.join(PRESETS)}")
        pts = norm.copy()
        span = (hi - lo) if hi > lo else 1.0
        pts[:, 0] = lo + norm[:, 0] * span
        return cls(pts, (lo, lo + span), table_size=table_size, unit_distance=unit_distance, name=key)

    @classmethod
    def labels(
        cls,
        labels: "Mapping[Any, Any] | Iterable[Any]",
        *,
        cmap: str = "tab20",
        opacity: float | None = None,
        unit_distance: float | None = None,
        name: str = "labels",
        smooth: bool = False,
    ) -> "LabelTransferFunction":
        """A TF for a label volume: ``{id: (r, g, b, a)}`` or a list of ids to colour
        distinctly; other ids hidden; nearest sampling, or with ``smooth`` interpolated
        per-label masks (smooth boundaries). See :class:`LabelTransferFunction`.

        Examples
        --------
        >>> tf = TransferFunction.labels({1: (1, 0, 0, 1), 2: (0, 1, 0, 0.5)})
        >>> tf.sampling, tf.visible
        ('nearest', (1, 2))
        >>> TransferFunction.labels([1, 2], smooth=True).sampling
        'smooth-labels'
        """
        return LabelTransferFunction(labels, cmap=cmap, opacity=opacity, unit_distance=unit_distance, name=name,
                                     smooth=smooth)

    def _bake(self) -> np.ndarray:
        lo, hi = self.value_range
        xs = np.linspace(lo, hi, self.table_size)
        vals = self.points[:, 0]
        table = np.empty((self.table_size, 4), np.float32)
        for c in range(4):
            # np.interp is right-continuous at repeated x, which gives clean steps.
            table[:, c] = np.interp(xs, vals, self.points[:, 1 + c])
        # An entry an ulp beside a zero-opacity control point (linspace rounding)
        # interpolates to ~1e-17 instead of 0: invisible, but it would make its entry
        # non-empty and switch skipping off around that point.
        table[table[:, 3] < _ALPHA_FLOOR, 3] = 0.0
        return table

    # -- queries ----------------------------------------------------------
    @property
    def scale(self) -> float:
        """Table entries per data unit: ``index = (v - lo) * scale``."""
        lo, hi = self.value_range
        return (self.table_size - 1) / (hi - lo)

    @property
    def is_transparent(self) -> bool:
        """True when the opacity is zero everywhere (every image is background)."""
        return bool(self._prefix[-1] == 0)

    @property
    def prefix(self) -> np.ndarray:
        """``prefix[i]``: entries among ``table[:i]`` with non-zero opacity (int64, n+1)."""
        return self._prefix

    def is_empty(self, lo: float, hi: float) -> bool:
        """Whether the opacity is zero for every value in ``[lo, hi]`` (O(1))."""
        return bool(range_is_empty(self._prefix, float(self.value_range[0]), self.scale, float(lo), float(hi)))

    def _entry_span(self, lo, hi) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :func:`kernels.classify.entry_span`: table entries a lookup of
        any value in ``[lo, hi]`` can touch."""
        lo = np.atleast_1d(np.asarray(lo, np.float64))
        hi = np.atleast_1d(np.asarray(hi, np.float64))
        first = np.empty(np.broadcast(lo, hi).shape, np.int64)
        last = np.empty_like(first)
        v_lo = float(self.value_range[0])
        for idx, (a, b) in enumerate(zip(*np.broadcast_arrays(lo, hi))):
            first.flat[idx], last.flat[idx] = entry_span(v_lo, self.scale, self.table_size, float(a), float(b))
        return first, last

    def classify(self, vmin: np.ndarray, vmax: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`is_empty`: True where a region ``[vmin, vmax]`` is *non-empty*.

        This is the per-brick reclassification a TF change costs: two table
        look-ups per brick, no pass over voxels.
        """
        lo = np.ascontiguousarray(vmin, dtype=np.float64)
        hi = np.ascontiguousarray(vmax, dtype=np.float64)
        if lo.shape != hi.shape:
            raise ParameterError(f"vmin/vmax: shapes differ, {lo.shape} vs {hi.shape}")
        if not np.all(lo <= hi):  # also false for NaN
            bad = int(np.count_nonzero(~(lo <= hi)))
            raise ParameterError(f"vmin/vmax: {bad} range(s) have vmin > vmax or NaN; expected vmin <= vmax")
        out = np.empty(lo.size, np.bool_)
        with parallel_section():
            classify_ranges(self._prefix, float(self.value_range[0]), self.scale, lo.ravel(), hi.ravel(), out)
        return out.reshape(lo.shape)

    def classify_bricks(self, volume, brick_size: int = 8) -> np.ndarray:
        """True for the bricks of ``volume`` (``Volume.brick_stats(brick_size)``) that
        may hold a sample of non-zero opacity: ``(nbz, nby, nbx)`` bool.

        What every brick-based index builds from; a label TF refines it with the
        volume's per-brick label sets.
        """
        stats = volume.brick_stats(brick_size)
        return self.refine_bricks(volume, brick_size, self.classify(stats.vmin, stats.vmax))

    def refine_bricks(self, volume, brick_size: int, occupied: np.ndarray) -> np.ndarray:
        """Brick occupancy from value ranges, refined by what the TF knows beyond ranges
        (the same array here; a label TF removes bricks without a visible id)."""
        return occupied

    def with_spikes(self, values, *, keep_opacity: bool) -> "TransferFunction":
        """A classification TF on this TF's table grid that is non-empty around ``values``.

        Isosurface rendering builds its empty-space indices for it: the two table
        entries around each isovalue get opacity 1 (values beyond the range clamp
        to an end entry, as lookups do), so any brick whose range holds an isovalue
        is non-empty. With ``keep_opacity`` this TF's own opacity stays too (iso+dvr).
        Colours are not meant to be looked at.
        """
        table = np.array(self.table, np.float32, copy=True)
        if not keep_opacity:
            table[:, 3] = 0.0
        n = self.table_size
        for v in np.atleast_1d(np.asarray(values, np.float64)):
            x = min(max((float(v) - self.value_range[0]) * self.scale, 0.0), n - 1.0)
            table[int(np.floor(x)), 3] = 1.0
            table[int(np.ceil(x)), 3] = 1.0
        out = TransferFunction.__new__(TransferFunction)
        out.points = self.points
        out.value_range = self.value_range
        out.table_size = n
        out.unit_distance = self.unit_distance
        out.name = f"{self.name}+iso"
        out.table = table
        out.table.flags.writeable = False
        out._prefix = _nonzero_prefix(table)
        return out

    def opacity_table(self, dt: float, unit_distance: float) -> np.ndarray:
        """Table with opacity corrected for step ``dt``: ``1 - (1 - a) ** (dt / unit)``.

        Colours stay straight (not premultiplied). The correction is applied per
        entry and entries are then interpolated, so a renderer pays no ``pow`` per
        sample; zero opacity stays exactly zero, so emptiness is unchanged.
        """
        if not (dt > 0 and unit_distance > 0):
            raise ParameterError(f"dt and unit_distance must be positive, got {dt}, {unit_distance}")
        out = np.array(self.table, dtype=np.float32, copy=True)
        a = self.table[:, 3].astype(np.float64)
        out[:, 3] = (1.0 - np.power(1.0 - np.minimum(a, 1.0), dt / unit_distance)).astype(np.float32)
        return out

    def __call__(self, values) -> np.ndarray:
        """RGBA (straight alpha) at ``values``, with the renderer's table interpolation."""
        v = np.asarray(values, dtype=np.float64)
        x = np.clip((v - self.value_range[0]) * self.scale, 0, self.table_size - 1)
        i0 = np.minimum(np.floor(x).astype(np.int64), self.table_size - 2)
        f = (x - i0)[..., None]
        return ((1 - f) * self.table[i0] + f * self.table[i0 + 1]).astype(np.float32)

    # -- persistence ------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "format": "sparsecast-tf/1",
            "name": self.name,
            "value_range": list(self.value_range),
            "table_size": self.table_size,
            "unit_distance": self.unit_distance,
            "points": self.points.tolist(),
        }

    @classmethod
    def from_dict(cls, d: dict, *, source: str = "dict") -> "TransferFunction":
        """A TF from the fields :meth:`to_dict` writes, checked against the schema of
        :mod:`sparsecast.tf_schema` (errors name the field)."""
        if isinstance(d, dict) and d.get("format") == LABELS_FORMAT:
            return LabelTransferFunction.from_dict(d, source=source)
        f = check_tf_dict(d, source)
        try:
            return cls(f["points"], f["value_range"], table_size=f["table_size"],
                       unit_distance=f["unit_distance"], name=f["name"])
        except TransferFunctionError as exc:
            raise TransferFunctionError(f"{source}: {exc}") from None

    def save(self, path: str | os.PathLike) -> Path:
        """Write the TF as JSON (atomically)."""
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(self.to_dict(), indent=2))
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "TransferFunction":
        """Read a TF written by :meth:`save` (a regular file of at most 4 MiB).

        Raises
        ------
        TransferFunctionError
            Not a regular file, too large, not JSON, or a field that does not fit the
            schema of :mod:`sparsecast.tf_schema` (the message names it).
        """
        p = Path(path)
        return cls.from_dict(read_tf_file(p), source=str(p))

    def with_range(self, value_range: tuple[float, float]) -> "TransferFunction":
        """The same shape of TF stretched over another value range."""
        lo0, hi0 = self.value_range
        lo, hi = value_range
        pts = self.points.copy()
        pts[:, 0] = lo + (pts[:, 0] - lo0) / (hi0 - lo0) * (hi - lo)
        return TransferFunction(pts, (lo, hi), table_size=self.table_size,
                                unit_distance=self.unit_distance, name=self.name)

    def __repr__(self) -> str:
        lo, hi = self.value_range
        return (f"TransferFunction(name={self.name!r}, points={len(self.points)}, "
                f"value_range=({lo:g}, {hi:g}), table_size={self.table_size})")


def _nonzero_prefix(table: np.ndarray) -> np.ndarray:
    """``prefix[i]``: entries among ``table[:i]`` with non-zero opacity, int64 of length n + 1
    (what makes "is ``[lo, hi]`` empty?" O(1) for every kind of TF)."""
    return np.concatenate(([0], np.cumsum(table[:, 3] > 0))).astype(np.int64)


def _colormap_points(name: str, threshold: float, max_opacity: float) -> np.ndarray:
    import matplotlib  # deferred: only colour-map presets need it

    cmap = matplotlib.colormaps[name]
    xs = np.linspace(threshold, 1.0, 32)
    # Skip the darkest fifth of the colour map: against a black background the
    # faint, barely opaque values would otherwise be invisible twice over.
    rgb = np.asarray(cmap(np.linspace(0.2, 1.0, 32)))[:, :3]
    alpha = max_opacity * (xs - threshold) / (1.0 - threshold)
    body = np.column_stack([xs, rgb, alpha])
    # Fully transparent from 0 to the threshold.
    head = np.array([[0.0, *rgb[0], 0.0]])
    return np.vstack([head, body]) if threshold > 0 else body

LABELS_FORMAT = "sparsecast-labels/1"
#: table entries of a label TF (one per id in the span, plus a hidden entry at each end)
_MAX_TABLE = 65536
#: most label ids a label TF spans (max id - min id + 1): uint16 segmentations fit
MAX_LABEL_SPAN = _MAX_TABLE - 2
_MIN_TABLE = 256


def _rgba(value: Any, where: str, opacity: float | None) -> tuple[float, float, float, float]:
    """Straight RGBA of a colour given as 3 or 4 numbers in [0, 1] or a Matplotlib name."""
    if isinstance(value, str):
        from matplotlib.colors import to_rgba  # deferred: only named colours need it

        try:
            rgba = tuple(float(c) for c in to_rgba(value))
        except ValueError:
            raise TransferFunctionError(f"{where}: {value!r} is not a colour name; expected e.g. 'red', "
                                        "'tab:blue', '#ff8800' or [r, g, b(, a)]") from None
    else:
        try:
            rgba = tuple(float(c) for c in value)
        except (TypeError, ValueError):
            raise TransferFunctionError(f"{where}: expected [r, g, b] or [r, g, b, a] in [0, 1] or a colour "
                                        f"name, got {value!r}") from None
        if len(rgba) == 3:
            rgba = rgba + (1.0,)
        if len(rgba) != 4:
            raise TransferFunctionError(f"{where}: expected 3 or 4 numbers (r, g, b[, a]), got {len(rgba)}")
        if not all(np.isfinite(rgba)) or min(rgba) < 0.0 or max(rgba) > 1.0:
            raise TransferFunctionError(f"{where}: expected numbers in [0, 1], got {list(rgba)}")
    if opacity is not None:
        rgba = rgba[:3] + (rgba[3] * opacity,)
    return rgba  # type: ignore[return-value]


def _label_id(key: Any, where: str) -> int:
    """An integer label id from an int, an integral float or a decimal string (JSON keys)."""
    if isinstance(key, bool):
        raise TransferFunctionError(f"{where}: expected an integer label id, got {key!r}")
    if isinstance(key, str):
        try:
            return int(key.strip(), 10)
        except ValueError:
            raise TransferFunctionError(f"{where}: expected an integer label id, got {key!r}") from None
    if isinstance(key, (int, np.integer)):
        return int(key)
    if isinstance(key, (float, np.floating)) and float(key).is_integer():
        return int(key)
    raise TransferFunctionError(f"{where}: expected an integer label id, got {key!r}")


# -- label volumes ---------------------------------------------------------

class LabelTransferFunction(TransferFunction):
    """Per-label colour and opacity for a label volume, sampled with the nearest voxel.

    A :class:`LabelTransferFunction` is a :class:`~sparsecast.transfer.TransferFunction`
    whose table holds one entry per integer label id, sampled with the *nearest*
    voxel (``sampling = "nearest"``), so ids are never blended. Labels not in the
    mapping, and labels given opacity 0, are hidden. Everything that works on a TF
    table works unchanged: the prefix count answers "is any label in ``[lo, hi]``
    visible?" for brick ranges, and the driver's nearest sampler reads table entry
    ``id - lo`` exactly (the table's scale is one entry per id, so no interpolation
    weight is ever fractional).

    Hiding labels whose ids lie between visible ones leaves those bricks inside a
    visible range; :meth:`LabelTransferFunction.visible_words` gives the visible set
    as a bit set, which the volume's per-brick label sets
    (:meth:`sparsecast.volume.Volume.brick_labels`) classify exactly.

    Smooth boundaries (``smooth=True``, ``sampling = "smooth-labels"``) interpolate
    per-label masks on the fly instead of reading the nearest id: at a sample, each
    visible label weighs the sum of the trilinear weights of the cell corners that
    hold it, and the sample's opacity and premultiplied colour are the weighted
    sums of the labels' (step-corrected) entries. Boundaries become smooth surfaces
    (shaded with the gradient of that opacity) and ids are still never blended into
    other ids. The eight corners are the trilinear footprint, so brick ranges and
    label sets skip exactly as for nearest sampling.

    The JSON format (``sparsecast-labels/1``)::

        {"format": "sparsecast-labels/1", "name": "organs", "smooth": false,
         "labels": {"1": [1, 0, 0, 1], "2": "tab:green", "7": [0.2, 0.4, 1.0, 0.3]}}

    Keys are label ids (integers as strings, JSON keys are strings); values are
    ``[r, g, b]``, ``[r, g, b, a]`` in ``[0, 1]`` or a Matplotlib colour name;
    ``smooth`` is optional (default false).

    Parameters
    ----------
    labels : mapping of int to colour, or iterable of int
        ``{id: (r, g, b, a)}`` (straight colour; ``(r, g, b)`` means opaque; a
        Matplotlib colour name is accepted), or just the ids to show, which get
        distinct colours from ``cmap``. Other ids are hidden.
    cmap : str
        Matplotlib colour map for ids given without a colour (qualitative maps such
        as ``tab20`` cycle).
    opacity : float, optional
        Multiplies every label's opacity (default 1).
    unit_distance : float, optional
        As for :class:`TransferFunction` (default: one voxel).
    name : str
        Label for messages and benchmark records.
    smooth : bool
        Interpolate per-label masks (smooth boundaries) instead of sampling the
        nearest voxel (default False).

    Examples
    --------
    >>> tf = LabelTransferFunction({1: (1, 0, 0, 1), 2: (0, 1, 0, 0.5)})
    >>> tf.is_empty(4, 9), tf.is_empty(0, 1)   # ranges are widened by an ulp-sized margin
    (True, False)
    """

    sampling = "nearest"

    def __init__(
        self,
        labels: Mapping[Any, Any] | Iterable[Any],
        *,
        cmap: str = "tab20",
        opacity: float | None = None,
        unit_distance: float | None = None,
        name: str = "labels",
        smooth: bool = False,
    ) -> None:
        if not isinstance(smooth, (bool, np.bool_)):
            raise TransferFunctionError(f"smooth: expected true or false, got {smooth!r}")
        if opacity is not None and not (np.isfinite(opacity) and 0.0 <= opacity <= 1.0):
            raise TransferFunctionError(f"opacity: expected a number in [0, 1], got {opacity!r}")
        if unit_distance is not None and not (np.isfinite(unit_distance) and unit_distance > 0):
            raise TransferFunctionError(f"unit_distance: expected a positive number or None, got {unit_distance!r}")
        if isinstance(labels, Mapping):
            items = [(_label_id(k, f"labels[{k!r}]"), v) for k, v in labels.items()]
        elif isinstance(labels, (str, bytes)) or not isinstance(labels, Iterable):
            raise TransferFunctionError(f"labels: expected a mapping id -> colour or a list of ids, "
                                        f"got {type(labels).__name__}")
        else:
            ids = sorted({_label_id(k, f"labels[{k!r}]") for k in labels})
            items = list(zip(ids, _distinct_colours(len(ids), cmap)))
        if not items:
            raise TransferFunctionError("labels: expected at least one label id")
        colours = {i: _rgba(v, f"labels[{i}]", opacity) for i, v in items}
        lo_id, hi_id = min(colours), max(colours)
        span = hi_id - lo_id + 1
        if span > MAX_LABEL_SPAN:
            raise TransferFunctionError(
                f"labels: ids span {lo_id}..{hi_id} ({span} ids); expected a span of at most {MAX_LABEL_SPAN}")
        size = max(_MIN_TABLE, span + 2)
        # Entry 0 is id lo_id - 1, so ids below and above the span clamp onto hidden
        # entries (the first, and the padding after the last id).
        v0 = float(lo_id - 1)
        table = np.zeros((size, 4), np.float32)
        for i, c in colours.items():
            table[i - lo_id + 1] = c
        self.labels = dict(sorted(colours.items()))
        self.cmap = cmap
        self.smooth = bool(smooth)
        self.sampling = "smooth-labels" if smooth else "nearest"
        self.value_range = (v0, v0 + size - 1)  # scale (size - 1) / span == 1 exactly
        self.table_size = size
        self.unit_distance = None if unit_distance is None else float(unit_distance)
        self.name = name
        self.table = table
        self.table.flags.writeable = False
        self._prefix = _nonzero_prefix(table)
        # One step per id: what the piecewise-linear view (viewer, repr) shows.
        pts = [(float(i), *c) for i, c in self.labels.items()]
        self.points = np.array(pts, np.float64)
        self.points.flags.writeable = False

    # -- queries ----------------------------------------------------------
    @property
    def visible(self) -> tuple[int, ...]:
        """Ids drawn with non-zero opacity, ascending."""
        return tuple(i for i, c in self.labels.items() if c[3] > 0)

    def visible_words(self, max_id: int) -> np.ndarray:
        """The visible ids in ``0..max_id`` as a bit set: ``(max_id // 64 + 1,)`` uint64.

        Bit ``i % 64`` of word ``i // 64`` is set when id ``i`` is visible (matching
        :meth:`sparsecast.volume.Volume.brick_labels`).
        """
        words = np.zeros(max(int(max_id), 0) // 64 + 1, np.uint64)
        for i in self.visible:
            if 0 <= i <= max_id:
                words[i // 64] |= np.uint64(1) << np.uint64(i % 64)
        return words

    def refine_bricks(self, volume, brick_size: int, occupied: np.ndarray) -> np.ndarray:
        """``occupied`` and "the brick's label set holds a visible id" (bricks of ``brick_size``).

        With the volume's per-brick label sets (:meth:`Volume.brick_labels`) this is
        exact for nearest sampling: a brick is non-empty iff a voxel of its apron
        window holds an id the TF maps to non-zero opacity. Volumes without label
        sets (non-integral values, too many ids) keep the range answer.
        """
        occ = occupied
        sets = volume.brick_labels(brick_size)
        if sets is None:
            return occ
        visible = sets.rank_words(self.visible)
        hit = np.empty(occ.size, np.bool_)
        any_visible(sets.words.reshape(occ.size, -1), visible, hit)
        return occ & hit.reshape(occ.shape)

    def __call__(self, values) -> np.ndarray:
        """RGBA (straight alpha) of the nearest label id to each value, as the renderer samples."""
        v = np.floor(np.asarray(values, dtype=np.float64) + 0.5)
        i = np.clip(v - self.value_range[0], 0, self.table_size - 1).astype(np.int64)
        return self.table[i]

    # -- variants ---------------------------------------------------------
    def with_range(self, value_range: tuple[float, float]) -> "LabelTransferFunction":
        """Label ids are names, not a scale: the same TF (nothing to stretch)."""
        return self

    def with_labels(self, changes: Mapping[Any, Any]) -> "LabelTransferFunction":
        """A copy with some labels recoloured, added, or hidden (colour ``None``)."""
        new = dict(self.labels)
        for k, v in changes.items():
            i = _label_id(k, f"labels[{k!r}]")
            if v is None:
                new.pop(i, None)
            else:
                new[i] = _rgba(v, f"labels[{i}]", None)
        if not new:
            new = {min(self.labels): (0.0, 0.0, 0.0, 0.0)}
        return LabelTransferFunction(new, cmap=self.cmap, unit_distance=self.unit_distance, name=self.name,
                                     smooth=self.smooth)

    def smoothed(self, smooth: bool = True) -> "LabelTransferFunction":
        """The same labels with smooth boundaries on (or off: nearest sampling)."""
        if bool(smooth) == self.smooth:
            return self
        return LabelTransferFunction(dict(self.labels), cmap=self.cmap, unit_distance=self.unit_distance,
                                     name=self.name, smooth=smooth)

    def hidden(self, ids: Iterable[Any]) -> "LabelTransferFunction":
        """A copy with the given ids hidden (their bricks then skip)."""
        return self.with_labels({i: None for i in ids})

    # -- persistence ------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "format": LABELS_FORMAT,
            "name": self.name,
            "unit_distance": self.unit_distance,
            "smooth": self.smooth,
            "labels": {str(i): [float(x) for x in c] for i, c in self.labels.items()},
        }

    @classmethod
    def from_dict(cls, d: dict, *, source: str = "dict") -> "LabelTransferFunction":  # type: ignore[override]
        """A label TF from the fields :meth:`to_dict` writes (errors name the field)."""
        if not isinstance(d, dict) or d.get("format") != LABELS_FORMAT:
            raise TransferFunctionError(f"{source}: format: expected {LABELS_FORMAT!r}")
        labels = d.get("labels")
        if not isinstance(labels, dict):
            raise TransferFunctionError(f"{source}: labels: expected an object {{\"id\": [r, g, b, a], ...}}, "
                                        f"got {type(labels).__name__}")
        if len(labels) > MAX_LABEL_SPAN:
            raise TransferFunctionError(f"{source}: labels: {len(labels)} entries; expected at most {MAX_LABEL_SPAN}")
        unit = d.get("unit_distance")
        name = d.get("name", "labels")
        if not isinstance(name, str) or len(name) > 200:
            raise TransferFunctionError(f"{source}: name: expected a string of at most 200 characters")
        smooth = d.get("smooth", False)
        if not isinstance(smooth, bool):
            raise TransferFunctionError(f"{source}: smooth: expected true or false, got {smooth!r}")
        try:
            return cls(labels, unit_distance=unit, name=name, smooth=smooth)
        except TransferFunctionError as exc:
            raise TransferFunctionError(f"{source}: {exc}") from None
        except TypeError:
            raise TransferFunctionError(f"{source}: unit_distance: expected a positive number or null, "
                                        f"got {unit!r}") from None

    def save(self, path: str | os.PathLike) -> Path:
        """Write the label TF as JSON (atomically)."""
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(self.to_dict(), indent=2))
        return Path(path)

    def __repr__(self) -> str:
        return (f"LabelTransferFunction(name={self.name!r}, labels={len(self.labels)}, "
                f"visible={len(self.visible)}" + (", smooth=True)" if self.smooth else ")"))


def _distinct_colours(n: int, cmap: str) -> list[tuple[float, float, float, float]]:
    """``n`` opaque colours from a Matplotlib colour map, cycling qualitative maps."""
    import matplotlib  # deferred: only generated colours need it

    try:
        cm = matplotlib.colormaps[cmap]
    except KeyError:
        raise TransferFunctionError(f"cmap: unknown colour map {cmap!r}; expected e.g. tab10, tab20, "
                                    "Set3 or viridis") from None
    qualitative = getattr(cm, "N", 256) <= 32
    if qualitative:
        return [tuple(float(c) for c in cm(i % cm.N)) for i in range(n)]  # type: ignore[misc]
    return [tuple(float(c) for c in cm(x)) for x in np.linspace(0.0, 1.0, max(n, 1))[:n]]  # type: ignore[misc]
