"""Spreading a frame's tiles over threads: chunks of tiles from a shared pool.

Kernels run with ``nogil=True``, so Python threads run them in parallel; the
pool hands out small chunks of tiles, so a thread that finishes an empty part of
the screen takes the next chunk (dynamic load balancing), and an interrupt
(Ctrl-C) stops the frame between chunks: the caller gets KeyboardInterrupt within
about a chunk's time (1/16 of a thread's share of the frame). Thread count: ``numba.get_num_threads()`` (``NUMBA_NUM_THREADS``).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, wait

import numba

from ..kernels.tiles import tile_count

__all__ = ["run_tiles", "n_threads", "limit_threads"]

#: chunks per thread: enough to balance sparse frames, few enough that the
#: per-chunk call (argument unboxing, ~10 us) stays negligible
CHUNKS_PER_THREAD = 16

#: seconds between checks for an interrupt while a frame renders
POLL_S = 0.02

_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_pool_lock = threading.Lock()


def n_threads() -> int:
    """Threads a frame is spread over."""
    return max(1, int(numba.get_num_threads()))


def limit_threads(n: int) -> None:
    """Render with at most ``n`` threads from the calling thread on (Numba's thread count
    is per calling thread): a one-thread Dask worker beside another on one machine must
    not take every core."""
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))


def _get_pool(n: int) -> ThreadPoolExecutor:
    global _pool, _pool_size
    with _pool_lock:
        if _pool is None or _pool_size != n:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(max_workers=n, thread_name_prefix="sparsecast-render")
            _pool_size = n
        return _pool


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
    n_tiles = int(tile_count(width, height))
    threads = min(n_threads(), n_tiles)
    if threads <= 1:
        kernel(0, n_tiles, *args)
        return
    n_chunks = min(n_tiles, threads * CHUNKS_PER_THREAD)
    bounds = [n_tiles * i // n_chunks for i in range(n_chunks + 1)]
    pool = _get_pool(threads)
    futures = [pool.submit(kernel, bounds[i], bounds[i + 1], *args) for i in range(n_chunks)]
    try:
        # Short waits, so that Ctrl-C (KeyboardInterrupt) and other signals reach
        # the caller within a chunk's time instead of at the end of the frame.
        pending = futures
        while pending:
            _, pending = wait(pending, timeout=POLL_S)
    except BaseException:
        for f in futures:
            f.cancel()  # chunks not started yet; running ones finish into the discarded frame
        raise
    for f in futures:
        f.result()  # re-raise a kernel's exception here
