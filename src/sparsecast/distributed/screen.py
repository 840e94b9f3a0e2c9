"""Which pixels can see a box: the screen rectangle a piece renders."""

from __future__ import annotations

import math

import numpy as np

from ..camera import Camera

__all__ = ["screen_rect"]


def screen_rect(camera: Camera, width: int, height: int, lo: np.ndarray, hi: np.ndarray
                ) -> tuple[int, int, int, int] | None:
    """Pixels whose primary ray may cross the world box ``[lo, hi]``, as ``(x0, y0, w, h)``.

    The projection of a box lying in front of the camera is the convex hull of its eight
    projected corners, so the pixels whose centres fall in the corners' bounding
    rectangle hold every ray through the box; one pixel of margin absorbs rounding.
    A perspective camera with a corner at or behind its eye plane (the camera inside
    or beside the box) gets the whole image. None: no pixel sees the box.

    Parameters
    ----------
    camera : Camera
    width, height : int
        Image size.
    lo, hi : (3,) array_like
        World-space corners of the box (x, y, z).
    """
    p = camera.ray_params(width, height)
    eye, fwd, right, up = p[0:3], p[3:6], p[6:9], p[9:12]
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    corners = np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    v = corners - eye
    if p[12]:  # perspective: screen coordinates are the ray direction's over its depth
        z = v @ fwd
        scale = float(np.abs(v).max()) or 1.0
        if z.min() <= 1e-9 * scale:
            return 0, 0, width, height
        u = (v @ right) / (right @ right) / z
        w = (v @ up) / (up @ up) / z
    else:
        u = (v @ right) / (right @ right)
        w = (v @ up) / (up @ up)
    # pixel centre x: u = (x + 0.5) / W * 2 - 1; y: v = 1 - (y + 0.5) / H * 2
    px = (u + 1.0) * 0.5 * width - 0.5
    py = (1.0 - w) * 0.5 * height - 0.5
    x0 = max(0, math.floor(px.min()) - 1)
    x1 = min(width, math.ceil(px.max()) + 2)
    y0 = max(0, math.floor(py.min()) - 1)
    y1 = min(height, math.ceil(py.max()) + 2)
    if x0 >= x1 or y0 >= y1:
        return None
    return x0, y0, x1 - x0, y1 - y0
