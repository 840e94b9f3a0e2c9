"""The timing rules of every benchmark: warm-up runs excluded, median of N, and
frames of several methods interleaved in rounds so that they share the machine's
drifts (clock, caches, neighbours) instead of one method getting a quiet minute.

Spread is reported as min / max and the median absolute deviation (MAD) of the
timed runs; cores busy is CPU time (every thread of the process) over wall time.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["median_ms", "Runs", "Frame", "timed_call", "interleaved"]

#: one frame of a method: returns ``(result, ms)``, ``ms`` the method's own frame time
#: or None to use the wall time around the call
Frame = Callable[[], tuple[Any, float | None]]


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


def timed_call(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    """``(result, wall ms, CPU ms)`` of one call; CPU time counts every thread of the
    process (Numba's, VTK's, llvmpipe's), so CPU / wall is the cores the call kept busy."""
    cpu0, t0 = time.process_time(), time.perf_counter()
    result = fn()
    return result, (time.perf_counter() - t0) * 1e3, (time.process_time() - cpu0) * 1e3


@dataclass
class Runs:
    """The timed frames of one method in an interleaved run.

    Attributes
    ----------
    ms : list of float
        Frame time of each timed run (the method's own figure, or the wall time).
    wall_ms, cpu_ms : list of float
        Wall and CPU (all threads) time around each timed call.
    result : Any
        What the last call returned.
    """

    ms: list[float] = field(default_factory=list)
    wall_ms: list[float] = field(default_factory=list)
    cpu_ms: list[float] = field(default_factory=list)
    result: Any = None

    def fields(self) -> dict[str, Any]:
        """The record fields: ``ms`` (median), ``ms_runs``, ``ms_min``, ``ms_max``,
        ``ms_mad`` (median absolute deviation), ``cpu_ms`` (median), ``cpu_ms_runs``,
        ``cores_busy`` (total CPU / total wall of the timed calls)."""
        med = statistics.median(self.ms)
        wall = sum(self.wall_ms)
        return {
            "ms": med, "ms_runs": list(self.ms), "ms_min": min(self.ms), "ms_max": max(self.ms),
            "ms_mad": statistics.median(abs(m - med) for m in self.ms),
            "cpu_ms": statistics.median(self.cpu_ms), "cpu_ms_runs": list(self.cpu_ms),
            "cores_busy": round(sum(self.cpu_ms) / wall, 2) if wall > 0 else None,
        }


def interleaved(frames: Mapping[str, Frame], repeat: int, warmup: int = 1) -> dict[str, Runs]:
    """Time the frames of several methods in rounds: ``warmup`` untimed rounds, then
    ``repeat`` timed ones, each calling every method once in turn (A B C A B C ...).

    Parameters
    ----------
    frames : mapping of name -> Frame
        One frame of each method on the same scene, in the order they take turns.
    repeat, warmup : int
        Timed rounds (at least 1) and untimed rounds before them.

    Returns
    -------
    dict of name -> Runs
        ``repeat`` timed runs per method, and its last result.
    """
    runs = {name: Runs() for name in frames}
    for _ in range(max(0, warmup)):
        for name, frame in frames.items():
            runs[name].result, _ = frame()
    for _ in range(max(1, repeat)):
        for name, frame in frames.items():
            (result, own_ms), wall, cpu = timed_call(frame)
            r = runs[name]
            r.result = result
            r.ms.append(wall if own_ms is None else own_ms)
            r.wall_ms.append(wall)
            r.cpu_ms.append(cpu)
    return runs
