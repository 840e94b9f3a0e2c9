"""One parallel region at a time where Numba's threading layer cannot take more; idle threads that sleep;
``nogil`` kernels spread over threads without Numba's threading layer.

Numba's ``workqueue`` layer (its fallback when neither TBB nor OpenMP loads)
aborts the whole process when two threads enter ``prange`` loops at once
("Concurrent access has been detected", exit code 134): two viewer clients, or
a render thread beside an index build. Every entry point that runs a
``parallel=True`` kernel (index builds, brick statistics, TF classification of
many ranges, the particle renderer) runs it inside :func:`parallel_section`,
which serialises callers under ``workqueue`` and costs nothing otherwise. (The
DVR driver does not use Numba's threading layer: it spreads tiles with
:func:`run_chunks`, ``nogil`` calls from Python threads, which any layer allows concurrently.)

Threads without ``prange``: :func:`run_chunks` calls a ``nogil`` kernel over pieces of
an index range from a few Python threads. Numba's parfor passes cost 3-4 s of a cold
compile per ``parallel=True`` kernel whatever its body (the deep k-d tree's cell
classification: 6.2-6.9 s with ``prange``, 3.0-3.3 s as a plain kernel), which a
first render pays; a kernel of milliseconds loses nothing to a few Python calls, and
needs no :func:`parallel_section`.

Idle OpenMP threads: with ``OMP_WAIT_POLICY`` unset, GNU OpenMP keeps a thread
that has run out of work spinning (300 000 rounds, milliseconds on a busy
machine) before it sleeps, at the end of every ``prange`` and between two of
them. That CPU time counts for the process and is taken from the threads still
working: measured on the wide BVH's diffuse rays (15 ms kernels, 2 threads on a
shared 2-core machine), 1.75 M rays per CPU-second spinning, 3.0 M passive.
:func:`configure_wait_policy` makes them sleep unless the user chose a policy.
"""

from __future__ import annotations

import contextlib
import importlib
import itertools
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

import numba

__all__ = ["parallel_section", "layer_is_thread_safe", "configure_wait_policy", "run_chunks"]

_lock = threading.RLock()
_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def configure_wait_policy() -> None:
    """``OMP_WAIT_POLICY=PASSIVE`` unless set: call before the first parallel kernel
    (the OpenMP runtime reads it when Numba loads it; ``sparsecast`` calls this on import)."""
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def _loads(module: str) -> bool:
    try:
        importlib.import_module(module)
        return True
    except Exception:  # ImportError, or OSError from a missing libtbb / libgomp
        return False


def layer_is_thread_safe() -> bool:
    """Whether the threading layer in use (or the one Numba will pick) takes concurrent callers."""
    wanted = str(numba.config.THREADING_LAYER).lower()
    if wanted == "workqueue":
        return False
    try:
        return numba.threading_layer() != "workqueue"
    except ValueError:  # no parallel kernel has run yet: predict the default choice
        return wanted != "default" or _loads("numba.np.ufunc.tbbpool") or _loads("numba.np.ufunc.omppool")


@contextlib.contextmanager
def parallel_section() -> Iterator[None]:
    """Run the body alone when the threading layer is ``workqueue``; freely otherwise."""
    if layer_is_thread_safe():
        yield
        return
    with _lock:
        yield


def _helpers() -> ThreadPoolExecutor:
    global _pool
    with _pool_lock:
        if _pool is None:  # helpers for every caller; a caller also works (see run_chunks)
            _pool = ThreadPoolExecutor(max_workers=max(1, numba.config.NUMBA_NUM_THREADS - 1),
                                       thread_name_prefix="sparsecast-chunks")
        return _pool


#: pieces per thread when run_chunks chooses the grain: items of uneven cost (a level's
#: tree nodes, bricks of mixed occupancy) balance over 16, and a piece's call (~10 us) stays small
PIECES_PER_THREAD = 16


def run_chunks(kernel: Callable, n: int, grain: int | None, *args) -> None:
    """Call ``kernel(first, last, *args)`` over ``[0, n)`` in pieces of ``grain`` items,
    on up to :func:`numba.get_num_threads` threads (the caller's setting, which
    :func:`sparsecast.render.schedule.limit_threads` lowers for a Dask worker).

    ``kernel`` is jitted with ``nogil=True`` and writes disjoint parts of its outputs
    per piece. The calling thread takes pieces too, and helper threads take the next
    free piece when they get to run, so a busy pool (another caller's pieces) slows a
    call down but never blocks it: a helper that starts after the last piece is taken
    finds nothing to do, and one that has not started is cancelled. A KeyboardInterrupt
    (or an error) in the caller's piece stops the helpers after their current piece.

    Parameters
    ----------
    kernel : jitted function with ``nogil=True``
        Handles items ``first .. last - 1``.
    n : int
        Items in all.
    grain : int or None
        Items per piece (>= 1): large enough that a piece outweighs a call (~10 us).
        None: :data:`PIECES_PER_THREAD` pieces per thread.
    *args
        Passed on to ``kernel``.
    """
    threads = max(1, int(numba.get_num_threads()))
    if grain is None:
        grain = max(1, -(-n // (threads * PIECES_PER_THREAD)))
    pieces = -(-n // grain)
    threads = min(threads, pieces)
    if threads <= 1:
        kernel(0, n, *args)
        return
    taken = itertools.count()  # next() is atomic under the GIL: each piece is taken once
    stop = []  # set when the caller gives up (Ctrl-C, a piece's error): no new pieces

    def work() -> None:
        for i in iter(taken.__next__, None):
            if i >= pieces or stop:
                return
            kernel(i * grain, min(n, (i + 1) * grain), *args)

    helpers = [_helpers().submit(work) for _ in range(threads - 1)]
    try:
        work()
    except BaseException:
        stop.append(True)
        raise
    finally:
        for f in helpers:
            if not f.cancel():
                f.result()  # wait for its piece (the outputs stay the caller's); re-raise its exception
