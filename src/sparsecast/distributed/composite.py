"""Front-to-back compositing of pieces' screen rectangles (premultiplied RGBA)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Layer", "over"]


@dataclass
class Layer:
    """What a piece (or a composited group of pieces) contributes to a frame.

    Attributes
    ----------
    x0, y0 : int
        Top-left pixel of the rectangle, in the frame's image.
    rgba : ndarray, shape (h, w, 4), float32
        Premultiplied RGBA over a transparent background.
    samples : ndarray, shape (h, w), int32
        Samples taken per pixel.
    stats : list of dict
        Per-piece statistics, in compositing order.
    composite_ms : float
        Time spent compositing the pieces below this layer.
    moved : int
        Bytes of layers handed from one task to another to make this one (an upper
        bound on the transfers: a task on the worker holding its input moves nothing).
    """

    x0: int
    y0: int
    rgba: np.ndarray
    samples: np.ndarray
    stats: list = field(default_factory=list)
    composite_ms: float = 0.0
    moved: int = 0

    @property
    def nbytes(self) -> int:
        return int(self.rgba.nbytes + self.samples.nbytes)


def over(near: Layer | None, far: Layer | None) -> Layer | None:
    """``near`` composited over ``far``: ``C = C_near + (1 - a_near) C_far`` on the union
    of their rectangles (either may be None: a piece no pixel sees)."""
    if near is None or far is None:
        return far if near is None else near
    if near.samples.size == 0 or far.samples.size == 0:
        # an empty layer (a piece whose rays took no sample) adds nothing but its statistics
        keep, empty = (far, near) if near.samples.size == 0 else (near, far)
        return Layer(keep.x0, keep.y0, keep.rgba, keep.samples, near.stats + far.stats,
                     near.composite_ms + far.composite_ms, near.moved + far.moved + keep.nbytes + empty.nbytes)
    t0 = time.perf_counter()
    h_n, w_n = near.samples.shape
    h_f, w_f = far.samples.shape
    x0, y0 = min(near.x0, far.x0), min(near.y0, far.y0)
    x1 = max(near.x0 + w_n, far.x0 + w_f)
    y1 = max(near.y0 + h_n, far.y0 + h_f)
    rgba = np.zeros((y1 - y0, x1 - x0, 4), np.float32)
    samples = np.zeros((y1 - y0, x1 - x0), np.int32)
    ny, nx = near.y0 - y0, near.x0 - x0
    rgba[ny:ny + h_n, nx:nx + w_n] = near.rgba
    samples[ny:ny + h_n, nx:nx + w_n] = near.samples
    fy, fx = far.y0 - y0, far.x0 - x0
    dst = rgba[fy:fy + h_f, fx:fx + w_f]
    dst += (1.0 - dst[..., 3:4]) * far.rgba
    samples[fy:fy + h_f, fx:fx + w_f] += far.samples
    ms = (time.perf_counter() - t0) * 1e3
    return Layer(x0, y0, rgba, samples, near.stats + far.stats, near.composite_ms + far.composite_ms + ms,
                 near.moved + far.moved + near.nbytes + far.nbytes)
