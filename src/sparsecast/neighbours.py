"""Nearest-neighbour statistics of point sets (``scipy.spatial.cKDTree``).

Particle and point-cloud defaults come from the data rather than from the bounding
box: a box says nothing about how points are spread inside it (a dark-matter halo
has most of its particles in a core a few per cent of its extent wide). Three
questions, one k-d tree each time:

``knn``            distances and indices of each point's ``k`` nearest neighbours;
``typical_spacing`` one length for the whole set: a quantile of the distance to the
                   ``k``-th neighbour;
``local_density``  per point: ``k / (4/3 pi d_k^3)``, the number density inside the
                   sphere reaching the ``k``-th neighbour (the SPH-style estimate).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ParameterError

__all__ = ["knn", "typical_spacing", "local_density"]


def _points(points, k: int, what: str = "points") -> tuple[np.ndarray, int]:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ParameterError(f"{what}: expected shape (n, 3), got {p.shape}")
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
        raise ParameterError(f"k: expected a positive integer, got {k!r}")
    return p, int(k)


def knn(points, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest other points of every point.

    Parameters
    ----------
    points : (n, 3) array_like
    k : int
        Neighbours per point, excluding the point itself; capped at ``n - 1``.

    Returns
    -------
    dist : (n, k') float64
        Distances, ascending (``k' = min(k, n - 1)``).
    idx : (n, k') int64
        Their indices into ``points``.
    """
    from scipy.spatial import cKDTree

    p, k = _points(points, k)
    k = min(k, len(p) - 1)
    if k < 1:
        return np.zeros((len(p), 0)), np.zeros((len(p), 0), np.int64)
    # k + 1: the nearest point of each query is the point itself (distance 0).
    dist, idx = cKDTree(p).query(p, k=k + 1, workers=-1)
    return dist[:, 1:], idx[:, 1:].astype(np.int64)


def typical_spacing(points, k: int = 8, quantile: float = 0.5) -> float:
    """A quantile (default the median) of the distance to the ``k``-th neighbour.

    The median follows where most points are (a halo's core, a scan's surface) and
    ignores a sparse background or outliers, which a mean over the box would not.
    Returns 0 for fewer than two distinct points.
    """
    if not 0.0 <= quantile <= 1.0:
        raise ParameterError(f"quantile: expected a number in [0, 1], got {quantile!r}")
    dist, _ = knn(points, k)
    if dist.size == 0:
        return 0.0
    return float(np.quantile(dist[:, -1], quantile))


def local_density(points, k: int = 16) -> np.ndarray:
    """Number density around every point, ``k / (4/3 pi d_k^3)`` (points per unit volume).

    Parameters
    ----------
    points : (n, 3) array_like
    k : int
        Neighbours the estimate spans (16: smooth enough to show substructure
        without washing out small clumps).

    Returns
    -------
    (n,) float64
        Positive densities; points that coincide with their ``k`` neighbours get the
        largest finite density of the set (or 1 when all coincide).
    """
    dist, _ = knn(points, k)
    n = len(dist)
    if dist.shape[1] == 0:
        return np.ones(n)
    kk = dist.shape[1]
    d = dist[:, -1]
    with np.errstate(divide="ignore"):
        rho = kk / (4.0 / 3.0 * math.pi * d**3)
    finite = np.isfinite(rho)
    if not finite.all():
        rho[~finite] = rho[finite].max() if finite.any() else 1.0
    return rho
