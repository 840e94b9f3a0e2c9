"""One parallel region at a time where Numba's threading layer cannot take more; idle threads that sleep.

Numba's ``workqueue`` layer (its fallback when neither TBB nor OpenMP loads)
aborts the whole process when two threads enter ``prange`` loops at once
("Concurrent access has been detected", exit code 134): two viewer clients, or
a render thread beside an index build. Every entry point that runs a
``parallel=True`` kernel (index builds, brick statistics, TF classification of
many ranges, the particle renderer) runs it inside :func:`parallel_section`,
which serialises callers under ``workqueue`` and costs nothing otherwise. (The
DVR driver does not use Numba's threading layer: it spreads tiles over its own
thread pool of ``nogil`` calls, which any layer allows concurrently.)

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
import os
import threading
from collections.abc import Iterator

import numba

__all__ = ["parallel_section", "layer_is_thread_safe", "configure_wait_policy"]

_lock = threading.RLock()


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
