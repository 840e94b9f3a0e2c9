"""One parallel region at a time where Numba's threading layer cannot take more.

Numba's ``workqueue`` layer (its fallback when neither TBB nor OpenMP loads)
aborts the whole process when two threads enter ``prange`` loops at once
("Concurrent access has been detected", exit code 134): two viewer clients, or
a render thread beside an index build. Every entry point that runs a
``parallel=True`` kernel (index builds, brick statistics, TF classification of
many ranges, the particle renderer) runs it inside :func:`parallel_section`,
which serialises callers under ``workqueue`` and costs nothing otherwise. (The
DVR driver does not use Numba's threading layer: it spreads tiles over its own
thread pool of ``nogil`` calls, which any layer allows concurrently.)
"""

from __future__ import annotations

import contextlib
import importlib
import threading
from collections.abc import Iterator

import numba

__all__ = ["parallel_section", "layer_is_thread_safe"]

_lock = threading.RLock()


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
