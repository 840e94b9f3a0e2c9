"""The one timing rule of every benchmark: warm-up runs excluded, median of N."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

__all__ = ["median_ms"]


def median_ms(fn: Callable[[], Any], repeat: int, warmup: int = 1) -> tuple[float, list[float], Any]:
    """Call ``fn`` ``warmup`` times untimed, then ``repeat`` times timed.

    Returns the median wall time in milliseconds, every timed run, and the last result.
    """
    result = None
    for _ in range(warmup):
        result = fn()
    runs = []
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        result = fn()
        runs.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(runs), runs, result
