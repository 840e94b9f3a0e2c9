"""Per-brick value ranges, computed in one parallel pass over the voxels."""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def brick_minmax(data, brick_size, nbz, nby, nbx, out_min, out_max):
    """Min/max of every brick, including a one-voxel apron.

    Brick ``(bk, bj, bi)`` covers the cells between voxel ``b*B`` and ``(b+1)*B`` on
    each axis, so a trilinear sample anywhere inside it reads voxels in
    ``[b*B, (b+1)*B]``. The range additionally includes one voxel on every side
    (``[b*B - 1, (b+1)*B + 1]``, clipped to the volume) so that samples on a brick
    face and central-difference gradients are covered too.

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
    nbricks = nbz * nby * nbx
    # One brick per iteration: bricks are independent, and a brick's voxels
    # (about (B+3)^3) are contiguous enough in x to stream from cache.
    for b in prange(nbricks):
        bk = b // (nby * nbx)
        rem = b - bk * nby * nbx
        bj = rem // nbx
        bi = rem - bj * nbx
        k0 = max(bk * brick_size - 1, 0)
        k1 = min((bk + 1) * brick_size + 1, nz - 1)
        j0 = max(bj * brick_size - 1, 0)
        j1 = min((bj + 1) * brick_size + 1, ny - 1)
        i0 = max(bi * brick_size - 1, 0)
        i1 = min((bi + 1) * brick_size + 1, nx - 1)
        lo = np.inf
        hi = -np.inf
        for k in range(k0, k1 + 1):
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    v = np.float64(data[k, j, i])
                    if v < lo:
                        lo = v
                    if v > hi:
                        hi = v
        out_min[bk, bj, bi] = lo
        out_max[bk, bj, bi] = hi
