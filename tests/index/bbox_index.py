"""A trivial exact index, registered by the tests: one interval per ray, the ray's
interval in the bounding box of the bricks that are non-empty for the TF.

It exists to show (and test) that an exact index is one module plus one
registration line: a record class, ``start_ray`` / ``next_interval`` overloads and
``traversal_record``, with no edit to the driver. Being registered, it runs
through every test of the generic exactness oracle (``test_exactness.py``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba.extending import overload

from sparsecast.index import SpatialIndex, register_index
from sparsecast.index.interval import next_interval, record_class, start_ray
from sparsecast.kernels.ray import clip_box

BRICK = 8


class BoxRecord(NamedTuple):
    lo: np.ndarray  # (3,) float64, index space
    hi: np.ndarray
    empty: bool


@overload(start_ray, jit_options={"cache": True})
def _start(record, scratch, ray, t_lo, t_hi):
    if record_class(record) is BoxRecord:

        def impl(record, scratch, ray, t_lo, t_hi):
            ox, oy, oz, dx, dy, dz = ray
            lo, hi = record.lo, record.hi
            t0, t1 = clip_box(ox, oy, oz, dx, dy, dz, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2])
            return (t0, t1, record.empty or t0 > t1)

        return impl


@overload(next_interval, jit_options={"cache": True})
def _next(record, scratch, ray, state, t_covered):
    if record_class(record) is BoxRecord:

        def impl(record, scratch, ray, state, t_covered):
            t0, t1, done = state
            if done:
                return math.inf, -math.inf, state
            return t0, t1, (t0, t1, True)

        return impl


@register_index
class BoundingBoxIndex(SpatialIndex):
    """The box of the non-empty 8^3 bricks (one-voxel apron included by the brick ranges)."""

    name = "test-bbox"

    def __init__(self, volume, tf) -> None:
        super().__init__(volume, tf)
        stats = volume.brick_stats(BRICK)
        occ = tf.classify(stats.vmin, stats.vmax)
        nz, ny, nx = volume.shape
        top = np.array([nx - 1, ny - 1, nz - 1], np.float64)
        if occ.any():
            k, j, i = np.nonzero(occ)
            lo = np.array([i.min(), j.min(), k.min()], np.float64) * BRICK
            hi = (np.array([i.max(), j.max(), k.max()], np.float64) + 1) * BRICK
            self.record = BoxRecord(np.minimum(lo, top), np.minimum(hi, top), False)
        else:
            self.record = BoxRecord(np.zeros(3), np.zeros(3), True)

    def traversal_record(self, view):
        return self.record
