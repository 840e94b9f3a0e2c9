"""Per-brick label sets: which label ids occur in each brick (with apron), as bit sets.

Label volumes are classified per brick by the *set* of ids present, not by their
range: hiding ids 6..10 of a segmentation must skip a brick holding only {0, 7}
even though its range [0, 7] spans visible ids 1..5. Ids are first replaced by
their rank among the ids the volume holds (so 2 000 sparse FreeSurfer ids cost 32
words, not 32 000 bits), and brick ``b`` records ranks of the voxels in
``[b*B - 1, (b+1)*B + 1]``: the footprint of :func:`.bricks.brick_minmax`, which
covers every nearest (and trilinear) sample inside the brick.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .bricks import _window


@njit(cache=True)
def count_values(data, lo, out):
    """``out[v - lo] += 1`` for every voxel value ``v`` (integral, ``lo <= v < lo + len(out)``).

    One pass, no temporary the size of the volume (``np.bincount`` would need the
    voxels as int64 first).
    """
    flat = data.reshape(-1)
    for i in range(flat.shape[0]):
        out[int(flat[i]) - lo] += 1


@njit(cache=True, parallel=True)
def brick_label_words(data, lo, rank_of, brick_size, nbz, nby, nbx, out):
    """Set bit ``r % 64`` of word ``r // 64`` of ``out[bk, bj, bi]`` for the rank ``r``
    of every voxel id in the brick's apron window.

    Parameters
    ----------
    data : (nz, ny, nx) ndarray
        Integral voxel ids.
    lo : int
        Smallest id.
    rank_of : (span,) int32
        Rank of id ``lo + i`` among the volume's ids.
    brick_size : int
    nbz, nby, nbx : int
        Brick counts per axis.
    out : (nbz, nby, nbx, n_words) uint64
        Zeroed on entry, written in place.
    """
    nz, ny, nx = data.shape
    for bk in prange(nbz):
        k0, k1 = _window(bk, brick_size, nz)
        for bj in range(nby):
            j0, j1 = _window(bj, brick_size, ny)
            for bi in range(nbx):
                i0, i1 = _window(bi, brick_size, nx)
                w = out[bk, bj, bi]
                for k in range(k0, k1 + 1):
                    for j in range(j0, j1 + 1):
                        for i in range(i0, i1 + 1):
                            r = np.uint64(rank_of[int(data[k, j, i]) - lo])
                            w[r >> np.uint64(6)] |= np.uint64(1) << (r & np.uint64(63))


@njit(cache=True)
def any_visible(words, visible, out):
    """``out[b] = any(words[b] & visible)`` for flat ``(n, n_words)`` brick words."""
    for b in range(words.shape[0]):
        hit = False
        for w in range(words.shape[1]):
            if words[b, w] & visible[w]:
                hit = True
                break
        out[b] = hit
