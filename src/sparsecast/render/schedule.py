"""Spreading a frame's tiles over threads.

Kernels run with ``nogil=True``, so Python threads run them in parallel. The tiles
go through :func:`sparsecast.kernels.parallel.run_chunks`, the one scheduler of the
package's ``nogil`` kernels (index builds, surface rays, particles): pieces of
about 1/16 of a thread's share of the frame are taken one at a time, so a thread
that finishes an empty part of the screen takes the next piece (dynamic load
balancing); the calling thread renders pieces too, so a render is never queued
behind another caller's work in the shared helper pool (two viewer clients, a
render beside an index build); and an interrupt (Ctrl-C) reaches the caller
between two of its pieces, after which the helpers take no new piece. Thread
count: ``numba.get_num_threads()`` (``NUMBA_NUM_THREADS``; :func:`limit_threads`).
"""

from __future__ import annotations

from collections.abc import Callable

import numba

from ..kernels.parallel import run_chunks
from ..kernels.tiles import tile_count

__all__ = ["run_tiles", "n_threads", "limit_threads"]


def n_threads() -> int:
    """Threads a frame is spread over."""
    return max(1, int(numba.get_num_threads()))


def limit_threads(n: int) -> None:
    """Render with at most ``n`` threads from the calling thread on (Numba's thread count
    is per calling thread): a one-thread Dask worker beside another on one machine must
    not take every core."""
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))


def run_tiles(kernel: Callable, width: int, height: int, *args) -> None:
    """Call ``kernel(first, last, *args)`` over all tiles of a ``width`` x ``height`` image.

    Parameters
    ----------
    kernel : jitted function with ``nogil=True``
        Renders tiles ``first..last-1``.
    width, height : int
        Size of the output arrays (tiles are :data:`sparsecast.kernels.tiles.TILE` pixels square).
    *args
        Passed on to ``kernel``.
    """
    run_chunks(kernel, int(tile_count(width, height)), None, *args)  # n_threads() threads
