"""A progress bar for chunk-by-chunk work (the scan of a lazy volume, a conversion).

:func:`chunk_progress` yields a :class:`ChunkProgress` whose :meth:`~ChunkProgress.advance`
any worker thread may call: a rich bar on stderr (markup off: the description is a
file name, printed as written), a caller's ``callback(done, total)``, or nothing.
The block tasks the work runs on dask's scheduler advance it themselves, so it counts
exactly the chunks (not dask's internal tasks).
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator

__all__ = ["ChunkProgress", "chunk_progress", "ProgressArg"]

#: what a ``progress=`` parameter takes: off (None/False), a rich bar (True), or a callback
ProgressArg = bool | Callable[[int, int], None] | None


class ChunkProgress:
    """Thread-safe counter of finished chunks, shown or reported as it advances."""

    def __init__(self, total: int, report: Callable[[int, int], None] | None) -> None:
        self.total = int(total)
        self.done = 0
        self._report = report
        self._lock = threading.Lock()

    def advance(self, n: int = 1) -> None:
        with self._lock:
            self.done += n
            done = self.done
        if self._report is not None:
            self._report(done, self.total)


@contextlib.contextmanager
def chunk_progress(progress: ProgressArg, total: int, description: str) -> Iterator[ChunkProgress]:
    """A :class:`ChunkProgress` over ``total`` chunks.

    Parameters
    ----------
    progress : bool, callable or None
        True: a rich progress bar on stderr, removed when done; a callable: called
        as ``progress(done, total)`` after every chunk; None or False: silent.
    total : int
        Chunks to expect.
    description : str
        The bar's label (printed verbatim).
    """
    if progress is None or progress is False:
        yield ChunkProgress(total, None)
        return
    if callable(progress):
        yield ChunkProgress(total, progress)
        return
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    console = Console(stderr=True, markup=False, highlight=False)
    with Progress(TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(),
                  TimeRemainingColumn(), console=console, transient=True) as bar:
        task = bar.add_task(description, total=total)
        yield ChunkProgress(total, lambda done, _total: bar.update(task, completed=done))
