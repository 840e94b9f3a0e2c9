"""Transfer functions: piecewise-linear RGBA over a value range, baked to a table.

A :class:`TransferFunction` maps a scalar value ``v`` to straight (not premultiplied)
RGBA. It is defined by control points and baked to a table of ``table_size`` entries
spanning ``value_range``; renderers look values up with linear interpolation between
neighbouring entries (values outside the range clamp to the end entries).

Emptiness queries ("is the opacity zero for every value in ``[lo, hi]``?") are O(1):
a prefix count of entries with non-zero opacity answers them without looking at
voxels, which is what makes rebuilding an empty-space index on a TF change cheap.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from .errors import ParameterError, TransferFunctionError
from ._util.atomic import atomic_path
from .tf_schema import check_tf_dict, read_tf_file
from .kernels.parallel import parallel_section
from .kernels.classify import classify_ranges, entry_span, range_is_empty

__all__ = ["TransferFunction", "PRESETS"]

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
        self._prefix = np.concatenate(([0], np.cumsum(self.table[:, 3] > 0))).astype(np.int64)

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
