"""Normals of an unoriented point cloud: PCA over each point's ``k`` nearest neighbours.

A raw range scan or a particle file carries positions only, yet splats (the RBVH's
discs, the exact BVH's ray-disc test) and shading need a normal per point. The
classic estimate (Hoppe et al. 1992) fits a plane to each point's neighbourhood: the
normal is the eigenvector of the smallest eigenvalue of the neighbourhood's
covariance matrix. All neighbourhoods are solved at once with NumPy's batched
``eigh`` (3x3 symmetric), in chunks so memory stays bounded on millions of points.

PCA gives a line, not a direction: the sign is chosen afterwards. Default: away
from the cloud's centroid, which is right for closed or convex-ish surfaces (a
scanned object seen from outside); ``towards=`` a viewpoint (the scanner's position)
orients an open scan towards where it was seen from. The renderers shade two-sided,
so a wrong sign darkens nothing; it only matters to code that reads the normals.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..neighbours import knn

__all__ = ["estimate_normals", "DEFAULT_K"]

#: neighbours per PCA fit: enough to average scanner noise, few enough to keep edges
DEFAULT_K = 16
#: points per batched eigen-decomposition (bounds the (chunk, k, 3) temporaries)
_CHUNK = 1 << 16


def estimate_normals(points, k: int = DEFAULT_K, *, towards=None) -> np.ndarray:
    """Unit normals of ``points`` by PCA over each point's neighbourhood.

    Parameters
    ----------
    points : (n, 3) array_like
        At least 3 points.
    k : int
        Neighbours per fit besides the point itself (>= 2; capped at ``n - 1``).
    towards : (3,) array_like, optional
        Orient every normal towards this viewpoint (``dot(n, towards - p) >= 0``).
        Default: away from the centroid of ``points``.

    Returns
    -------
    (n, 3) float64
        Unit normals. Where a neighbourhood is degenerate (all on a line, or all in
        one spot) the plane is not defined and the normal is some unit vector
        perpendicular to the line.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ParameterError(f"points: expected shape (n, 3), got {p.shape}")
    if len(p) < 3:
        raise ParameterError(f"points: a normal needs a plane through at least 3 points, got {len(p)}")
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 2:
        raise ParameterError(f"k: expected an integer >= 2 (neighbours per plane fit), got {k!r}")
    _, idx = knn(p, int(k))
    normals = np.empty_like(p)
    for s in range(0, len(p), _CHUNK):
        nb = np.concatenate([p[s:s + _CHUNK, None, :], p[idx[s:s + _CHUNK]]], axis=1)  # (c, k+1, 3)
        nb -= nb.mean(axis=1, keepdims=True)
        cov = np.einsum("cki,ckj->cij", nb, nb)
        _, vec = np.linalg.eigh(cov)  # eigenvalues ascending: column 0 is the plane normal
        normals[s:s + _CHUNK] = vec[:, :, 0]
    if towards is None:
        out = p - p.mean(axis=0)
    else:
        v = np.asarray(towards, dtype=np.float64)
        if v.shape != (3,) or not np.isfinite(v).all():
            raise ParameterError(f"towards: expected a finite point (x, y, z), got {towards!r}")
        out = v - p
    flip = np.einsum("ni,ni->n", normals, out) < 0
    normals[flip] *= -1.0
    return normals
