"""The naive index's traversal: the whole clip interval as one interval."""

from __future__ import annotations

import math
from typing import NamedTuple

from numba.extending import overload

from ..interval import next_interval, record_class, start_ray

__all__ = ["NaiveRecord"]


class NaiveRecord(NamedTuple):
    """No arrays: every lattice sample of the clip box is taken."""

    unused: int = 0


@overload(start_ray, jit_options={"cache": True}, inline="always")
def _start(record, scratch, ray, t_lo, t_hi):
    if record_class(record) is NaiveRecord:
        return lambda record, scratch, ray, t_lo, t_hi: (t_lo, t_hi, False)


@overload(next_interval, jit_options={"cache": True}, inline="always")
def _next(record, scratch, ray, state, t_covered):
    if record_class(record) is NaiveRecord:

        def impl(record, scratch, ray, state, t_covered):
            t_lo, t_hi, done = state
            if done:
                return math.inf, -math.inf, state
            return t_lo, t_hi, (t_lo, t_hi, True)

        return impl
