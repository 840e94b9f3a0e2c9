"""Per-brick value ranges, computed in one parallel pass over the voxels."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _window(b, brick_size, n):
    """Voxel range ``[b*B - 1, (b+1)*B + 1]`` of brick ``b`` (with apron), clipped to ``[0, n-1]``."""
    return max(b * brick_size - 1, 0), min((b + 1) * brick_size + 1, n - 1)


@njit(cache=True, parallel=True)
def brick_minmax(data, brick_size, nbz, nby, nbx, out_min, out_max):
    """Min/max of every brick, including a one-voxel apron.

    Brick ``(bk, bj, bi)`` covers the cells between voxel ``b*B`` and ``(b+1)*B`` on
    each axis, so a trilinear sample anywhere inside it reads voxels in
    ``[b*B, (b+1)*B]``. The range additionally includes one voxel on every side
    (``[b*B - 1, (b+1)*B + 1]``, clipped to the volume) so that samples on a brick
    face and central-difference gradients are covered too.

    A box min/max is separable, so it is computed axis by axis: each z-slice
    (in parallel) reduces its rows over x windows and then over y windows, and a
    last small pass reduces the per-slice results over z windows. Every voxel is
    read about ``(B + 3) / B`` times, in memory order, instead of ``((B + 3) / B)^3``
    times for a brick-by-brick loop.

    Parameters
    ----------
    data : ndarray, shape (nz, ny, nx)
        Voxel values (any real dtype).
    brick_size : int
        Cells per brick edge ``B``.
    nbz, nby, nbx : int
        Brick counts per axis.
    out_min, out_max : ndarray of float64, shape (nbz, nby, nbx)
        Written in place.
    """
    nz, ny, nx = data.shape
    # Per z-slice results, kept in float64 (exact for every supported dtype).
    slice_min = np.empty((nz, nby, nbx), np.float64)
    slice_max = np.empty((nz, nby, nbx), np.float64)
    for k in prange(nz):
        row_min = np.empty((ny, nbx), np.float64)
        row_max = np.empty((ny, nbx), np.float64)
        for j in range(ny):
            for bi in range(nbx):
                i0, i1 = _window(bi, brick_size, nx)
                lo = np.inf
                hi = -np.inf
                for i in range(i0, i1 + 1):
                    v = np.float64(data[k, j, i])
                    lo = min(lo, v)
                    hi = max(hi, v)
                row_min[j, bi] = lo
                row_max[j, bi] = hi
        for bj in range(nby):
            j0, j1 = _window(bj, brick_size, ny)
            for bi in range(nbx):
                lo = np.inf
                hi = -np.inf
                for j in range(j0, j1 + 1):
                    lo = min(lo, row_min[j, bi])
                    hi = max(hi, row_max[j, bi])
                slice_min[k, bj, bi] = lo
                slice_max[k, bj, bi] = hi
    for bk in prange(nbz):
        k0, k1 = _window(bk, brick_size, nz)
        for bj in range(nby):
            for bi in range(nbx):
                lo = np.inf
                hi = -np.inf
                for k in range(k0, k1 + 1):
                    lo = min(lo, slice_min[k, bj, bi])
                    hi = max(hi, slice_max[k, bj, bi])
                out_min[bk, bj, bi] = lo
                out_max[bk, bj, bi] = hi
