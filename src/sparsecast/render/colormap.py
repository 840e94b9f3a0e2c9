"""Per-element values to colours through a matplotlib colour map, over a robust range."""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError

__all__ = ["map_values", "robust_range", "DEFAULT_PERCENTILES"]

#: the range a colour map spans by default: a few outliers (one particle in a
#: thousand far denser or brighter than the rest) must not squeeze every other
#: value into one colour
DEFAULT_PERCENTILES = (1.0, 99.0)


def robust_range(values: np.ndarray, percentiles: tuple[float, float] = DEFAULT_PERCENTILES) -> tuple[float, float]:
    """The ``percentiles`` of ``values`` (n,), widened to a non-empty interval."""
    v = np.asarray(values, dtype=np.float64)
    if v.size == 0:
        return 0.0, 1.0
    lo, hi = (float(x) for x in np.percentile(v, percentiles))
    if not hi > lo:  # constant values: any colour is right, keep the map's middle
        lo, hi = lo - 0.5, hi + 0.5
    return lo, hi


def map_values(values, cmap: str = "viridis", value_range: tuple[float, float] | None = None
               ) -> tuple[np.ndarray, tuple[float, float]]:
    """Straight RGB (n, 3) in [0, 1] of ``values`` (n,) through colour map ``cmap``.

    Parameters
    ----------
    values : (n,) array_like
    cmap : str
        A matplotlib colour map name (``viridis``, ``magma``, ``inferno``, ...).
    value_range : (lo, hi), optional
        Values mapped to the map's ends (clamped beyond); default
        :func:`robust_range` (1st and 99th percentile).

    Returns
    -------
    rgb : (n, 3) float64
    value_range : (lo, hi) used
    """
    import matplotlib  # deferred: only colour mapping needs it

    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 1:
        raise ParameterError(f"values: expected shape (n,), got {v.shape}")
    try:
        cm = matplotlib.colormaps[cmap]
    except (KeyError, TypeError):
        raise ParameterError(f"cmap: expected a matplotlib colour map name such as viridis, magma, inferno, "
                             f"plasma, turbo; got {cmap!r}") from None
    if value_range is None:
        lo, hi = robust_range(v)
    else:
        try:
            lo, hi = (float(x) for x in value_range)
        except (TypeError, ValueError):
            raise ParameterError(f"color_range: expected two numbers (lo, hi), got {value_range!r}") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
            raise ParameterError(f"color_range: expected finite lo < hi, got {value_range!r}")
    x = np.clip((v - lo) / (hi - lo), 0.0, 1.0)
    return np.asarray(cm(x), dtype=np.float64)[:, :3], (lo, hi)
