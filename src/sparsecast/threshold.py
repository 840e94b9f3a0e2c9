"""The default transparency threshold of the colour-map presets, from a volume's histogram.

``TransferFunction.preset(name, range, threshold=t)`` makes values below the fraction
``t`` of the range transparent; that is what makes space empty. A fixed 0.1 suits
volumes whose background sits at the bottom of the range (air in most CT, zero in
simulation fields and segmentations), but not a scan whose background noise lies
higher: the shared tooth CT's background peak is at 30 % of its range, so with 0.1 the
whole box renders as fog and nothing is skipped. :func:`auto_threshold` keeps 0.1 unless
the histogram's highest peak (taken as the background) reaches above it, and then puts
the threshold on that peak's upper flank.
"""

from __future__ import annotations

import numpy as np

__all__ = ["auto_threshold", "DEFAULT_THRESHOLD"]

#: the presets' threshold where the histogram does not call for another
DEFAULT_THRESHOLD = 0.1


def auto_threshold(volume, value_range: tuple[float, float] | None = None, *, floor: float = DEFAULT_THRESHOLD,
                   bins: int = 256, flank: float = 0.05, cap: float = 0.9) -> float:
    """Fraction of ``value_range`` below which a colour-map preset should be transparent.

    The histogram's highest bin is taken as the background; walking up from it, the
    first bin holding less than ``flank`` of the peak's count ends its upper flank. The
    result is ``max(floor, that bin's lower edge)`` as a fraction of ``value_range``,
    or ``floor`` when the flank reaches ``cap`` of the range or beyond (no background
    peak below the data of interest: a flat histogram, a bright background).

    Parameters
    ----------
    volume : Volume or BrickedVolume
        Anything with ``histogram(bins) -> (counts, edges)`` and ``value_range``
        (dense volumes sample at most about 4 M voxels; bricked ones use their scan).
    value_range : (float, float), optional
        The TF's range (default: the volume's).
    floor, bins, flank, cap
        The smallest threshold returned; histogram bins; the flank's end as a fraction
        of the peak's count; the largest threshold returned.

    Returns
    -------
    float
        A fraction in ``[floor, cap)``.

    Examples
    --------
    >>> import numpy as np, sparsecast as sc
    >>> a = np.full((32, 32, 32), 80, np.uint8); a[8:24, 8:24, 8:24] = 250   # background at 80 of 0..250
    >>> a[0, 0, 0] = 0
    >>> auto_threshold(sc.Volume(a)) > 80 / 250   # just above the background peak
    True
    >>> auto_threshold(sc.Volume(np.where(a == 80, 0, a).astype(np.uint8)))   # background at the bottom
    0.1
    """
    lo, hi = (float(v) for v in (value_range if value_range is not None else volume.value_range))
    if not hi > lo:
        return floor
    histogram = getattr(volume, "histogram", None)
    if histogram is None:  # a volume type that keeps no histogram: the fixed default
        return floor
    counts, edges = histogram(bins)
    counts = np.asarray(counts, np.float64)
    if counts.sum() <= 0:
        return floor
    peak = int(np.argmax(counts))
    end = peak
    while end < counts.size and counts[end] >= flank * counts[peak]:
        end += 1
    value = float(edges[min(end, counts.size)])
    frac = (value - lo) / (hi - lo)
    if not frac < cap:
        return floor
    return max(floor, frac)
