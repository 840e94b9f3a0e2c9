"""Box min/max over per-axis windows of one chunk, and value counts: the per-chunk
kernels of the chunk-parallel scan (:mod:`sparsecast.storage.scan`).

A brick's apron range is a min/max over a box, and a box min/max over a volume split
into chunks is the min/max of the partial boxes each chunk holds. So a chunk reduces
the part of every brick window that lies inside it, and the scan combines the partial
results: exact for any chunking (min and max are exact and order-free on NaN-free
data), with no overlap between chunks to read.

Both kernels are serial and release the GIL: the scan runs one per chunk on several
threads (``parallel=True`` kernels on every thread would oversubscribe the cores).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["window_minmax", "count_values_nogil"]


@njit(cache=True, nogil=True)
def window_minmax(data, zlo, zhi, ylo, yhi, xlo, xhi, out_min, out_max):
    """Min/max of ``data`` over every box ``[zlo[a], zhi[a]] x [ylo[b], yhi[b]] x [xlo[c], xhi[c]]``.

    Separable and in the voxels' own dtype, so the inner loops are element-wise over
    contiguous rows (vectorised by LLVM): the z windows reduce whole planes, then the
    y windows reduce rows of the reduced planes, then the x windows the reduced rows.
    Every voxel is read once per z window that holds it ((B + 3) / B times for brick
    windows of B cells and a one-voxel apron).

    Parameters
    ----------
    data : ndarray, shape (nz, ny, nx)
        The chunk's voxels (any real dtype, NaN-free).
    zlo, zhi, ylo, yhi, xlo, xhi : ndarray of int64, shapes (nwz,), (nwz,), (nwy,), ...
        Inclusive window bounds in chunk-local voxel indices, ``lo <= hi``.
    out_min, out_max : ndarray of float64, shape (nwz, nwy, nwx)
        Written in place.
    """
    nz, ny, nx = data.shape
    pmin = np.empty((ny, nx), data.dtype)
    pmax = np.empty((ny, nx), data.dtype)
    rmin = np.empty(nx, data.dtype)
    rmax = np.empty(nx, data.dtype)
    for a in range(zlo.shape[0]):
        k0 = zlo[a]
        for j in range(ny):
            for i in range(nx):
                pmin[j, i] = data[k0, j, i]
                pmax[j, i] = data[k0, j, i]
        for k in range(k0 + 1, zhi[a] + 1):
            for j in range(ny):
                src = data[k, j]
                lo_row = pmin[j]
                hi_row = pmax[j]
                for i in range(nx):
                    v = src[i]
                    lo_row[i] = min(lo_row[i], v)
                    hi_row[i] = max(hi_row[i], v)
        for b in range(ylo.shape[0]):
            j0 = ylo[b]
            for i in range(nx):
                rmin[i] = pmin[j0, i]
                rmax[i] = pmax[j0, i]
            for j in range(j0 + 1, yhi[b] + 1):
                lo_row = pmin[j]
                hi_row = pmax[j]
                for i in range(nx):
                    rmin[i] = min(rmin[i], lo_row[i])
                    rmax[i] = max(rmax[i], hi_row[i])
            for c in range(xlo.shape[0]):
                lo = rmin[xlo[c]]
                hi = rmax[xlo[c]]
                for i in range(xlo[c] + 1, xhi[c] + 1):
                    lo = min(lo, rmin[i])
                    hi = max(hi, rmax[i])
                out_min[a, b, c] = np.float64(lo)
                out_max[a, b, c] = np.float64(hi)


@njit(cache=True, nogil=True)
def count_values_nogil(data, lo, out):
    """``out[v - lo] += 1`` for every voxel value ``v`` of an integer chunk
    (``lo <= v < lo + len(out)``); no int64 copy of the chunk, as ``np.bincount`` makes.

    Four interleaved sub-histograms: consecutive equal values (the background of a
    sparse volume) would otherwise make every increment wait for the previous one to
    the same counter (twice as fast on sparse data, and on random data too).
    """
    n = out.shape[0]
    sub = np.zeros((4, n), np.int32)  # a chunk holds fewer than 2^31 voxels
    nz, ny, nx = data.shape
    tail = nx - nx % 4
    for k in range(nz):
        for j in range(ny):
            row = data[k, j]
            for i in range(0, tail, 4):
                sub[0, np.int64(row[i]) - lo] += 1
                sub[1, np.int64(row[i + 1]) - lo] += 1
                sub[2, np.int64(row[i + 2]) - lo] += 1
                sub[3, np.int64(row[i + 3]) - lo] += 1
            for i in range(tail, nx):
                sub[0, np.int64(row[i]) - lo] += 1
    for r in range(4):
        for v in range(n):
            out[v] += sub[r, v]
