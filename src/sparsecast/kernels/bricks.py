"""Per-brick value ranges, computed in one parallel pass over the voxels.

Two passes give the same float64 ranges: :func:`brick_ranges` (what
:meth:`sparsecast.volume.Volume.brick_stats` runs) splits the volume into slabs of
whole bricks and reduces each with the vectorised separable kernel of the scan
(:func:`~.windows.window_minmax`) on a thread pool, and :func:`brick_minmax` is one
``parallel=True`` kernel that converts every voxel to float64 first (four to eight
times slower; the LBVH's per-build voting pass keeps it).
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numba import njit, prange

from .windows import window_minmax

__all__ = ["brick_windows", "brick_ranges", "warm_brick_ranges", "brick_minmax"]

#: bytes of voxels one task of :func:`brick_ranges` reads: per-task overhead (tens of
#: microseconds) vanishes, and a volume of tens of MiB still makes tasks for every thread
TASK_BYTES = 4 << 20


def brick_windows(n: int, brick_size: int) -> tuple[np.ndarray, np.ndarray]:
    """Inclusive voxel windows ``[b*B - 1, (b+1)*B + 1]`` of the bricks along an axis of
    ``n`` voxels, clipped to ``[0, n-1]``: ``(lo, hi)``, int64 arrays of shape (nb,)."""
    nb = max(1, -(-(n - 1) // brick_size))
    b = np.arange(nb, dtype=np.int64)
    return np.maximum(b * brick_size - 1, 0), np.minimum((b + 1) * brick_size + 1, n - 1)


def _task(data, wins, bz: slice, out_min, out_max) -> None:
    """Reduce the brick rows ``bz`` (every brick along y and x): the voxels of their windows
    are the slab of whole planes ``data[z0:z1+1]``, a C-contiguous view (one Numba type)."""
    (zlo, zhi), (ylo, yhi), (xlo, xhi) = (wins[0][0][bz], wins[0][1][bz]), wins[1], wins[2]
    z0, z1 = int(zlo[0]), int(zhi[-1])
    window_minmax(data[z0:z1 + 1], zlo - z0, zhi - z0, ylo, yhi, xlo, xhi, out_min[bz], out_max[bz])


def brick_ranges(data: np.ndarray, brick_size: int, out_min: np.ndarray, out_max: np.ndarray,
                 *, workers: int | None = None) -> None:
    """Min/max of every brick with its one-voxel apron, on ``workers`` threads.

    Brick ``(bk, bj, bi)`` ranges over voxels ``[b*B - 1, (b+1)*B + 1]`` per axis,
    clipped (:func:`brick_windows`), as :func:`brick_minmax`. Each task takes the brick
    rows ``bk0 .. bk1`` (whole planes: splitting planes as well measured no faster on
    1024^3, and would need a second specialisation), reads the voxels of their windows
    (two or three planes more than the bricks' own) and writes its own rows of the
    outputs, so tasks share nothing. The kernel reduces in the voxels' dtype and
    converts the result to float64: min and max are exact, so the ranges equal
    :func:`brick_minmax`'s (which converts first) on NaN-free data, bit for bit up to
    the sign of a zero.

    Parameters
    ----------
    data : ndarray, shape (nz, ny, nx)
        C-contiguous voxels (any real dtype, NaN-free).
    brick_size : int
        Cells per brick edge ``B``.
    out_min, out_max : ndarray of float64, shape (nbz, nby, nbx)
        C-contiguous, written in place; ``nb = max(1, ceil((n - 1) / B))`` per axis.
    workers : int, optional
        Threads (default :func:`numba.get_num_threads`, as the renderer's pool).
    """
    wins = [brick_windows(int(n), brick_size) for n in data.shape]
    nbz = len(wins[0][0])
    workers = max(1, int(workers or numba.get_num_threads()))
    if workers == 1 or data.nbytes <= 2 * TASK_BYTES or nbz == 1:
        _task(data, wins, slice(0, nbz), out_min, out_max)
        return
    row = brick_size * data.shape[1] * data.shape[2] * data.dtype.itemsize  # bytes of one brick row
    # Tasks of about TASK_BYTES, and at least four per thread to balance them.
    step = max(1, min(TASK_BYTES // max(1, row), math.ceil(nbz / (4 * workers))))
    jobs = [slice(bz, min(bz + step, nbz)) for bz in range(0, nbz, step)]
    with ThreadPoolExecutor(min(workers, len(jobs))) as pool:
        # list(): re-raise a task's exception here
        list(pool.map(lambda bz: _task(data, wins, bz, out_min, out_max), jobs))


def warm_brick_ranges(tiny: np.ndarray) -> None:
    """Compile (or load) the kernel :func:`brick_ranges` runs for voxels typed as ``tiny``
    (a 3^3 array of the real dtype and writeable flag, which Numba types apart)."""
    w = np.zeros(1, np.int64)
    out = np.empty((1, 1, 1))
    window_minmax(tiny, w, w, w, w, w, w, out, out)


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
