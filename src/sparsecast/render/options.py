"""Validation of the render options shared by the volume and particle renderers."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import ParameterError
from ..kernels.shade import SHADING_SIZE

__all__ = ["MAX_IMAGE_SIDE", "MAX_IMAGE_PIXELS", "DEFAULT_SHADING", "NAMED_BACKGROUNDS", "check_size",
           "shading_array", "background_array", "rect_bounds", "initial_rgba", "world_clip"]

MAX_IMAGE_SIDE = 16384
MAX_IMAGE_PIXELS = 1 << 26  # 64 Mpixel: 1 GiB of float RGBA

#: Blinn-Phong coefficients used by ``shading=True``.
DEFAULT_SHADING: dict[str, float] = {"ka": 0.3, "kd": 0.7, "ks": 0.25, "shininess": 24.0}

NAMED_BACKGROUNDS = {
    "transparent": (0.0, 0.0, 0.0, 0.0),
    "black": (0.0, 0.0, 0.0, 1.0),
    "white": (1.0, 1.0, 1.0, 1.0),
    "gray": (0.5, 0.5, 0.5, 1.0),
}


def check_size(width, height) -> tuple[int, int]:
    """Image size as two ints in ``1..MAX_IMAGE_SIDE`` with at most ``MAX_IMAGE_PIXELS``."""
    out = []
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise ParameterError(f"{name}: expected an integer number of pixels, got {v!r}")
        v = int(v)
        if not 1 <= v <= MAX_IMAGE_SIDE:
            raise ParameterError(f"{name}: expected 1..{MAX_IMAGE_SIDE} pixels, got {v}")
        out.append(v)
    if out[0] * out[1] > MAX_IMAGE_PIXELS:
        raise ParameterError(
            f"image size: {out[0]}x{out[1]} is {out[0] * out[1]} pixels; expected at most {MAX_IMAGE_PIXELS}"
        )
    return out[0], out[1]


def shading_array(shading) -> np.ndarray:
    """``shading=`` as the (5,) array the kernels read (see :mod:`sparsecast.kernels.shade`)."""
    arr = np.zeros(SHADING_SIZE, np.float64)
    if shading is False or shading is None:
        return arr
    params = dict(DEFAULT_SHADING)
    if isinstance(shading, Mapping):
        unknown = set(shading) - set(params)
        if unknown:
            raise ParameterError(f"shading: unknown keys {sorted(unknown)}; expected {sorted(params)}")
        params.update({k: float(v) for k, v in shading.items()})
    elif shading is not True:
        raise ParameterError(f"shading: expected a bool or a mapping, got {shading!r}")
    for k, v in params.items():
        if not (np.isfinite(v) and v >= 0):
            raise ParameterError(f"shading[{k!r}]: expected a non-negative number, got {v}")
    arr[:] = (1.0, params["ka"], params["kd"], params["ks"], params["shininess"])
    return arr


def background_array(background) -> np.ndarray:
    """``background=`` as straight RGBA (4,) float64."""
    if isinstance(background, str):
        try:
            return np.array(NAMED_BACKGROUNDS[background.lower()], np.float64)
        except KeyError:
            raise ParameterError(
                f"background: unknown colour {background!r}; expected one of {sorted(NAMED_BACKGROUNDS)} "
                "or 3-4 numbers in [0, 1]"
            ) from None
    arr = np.asarray(background, dtype=np.float64).ravel()
    if arr.size == 3:
        arr = np.append(arr, 1.0)
    if arr.size != 4 or not np.all((arr >= 0) & (arr <= 1)):
        raise ParameterError(f"background: expected 3-4 numbers in [0, 1], got {background!r}")
    return arr


def rect_bounds(rect, width: int, height: int) -> tuple[int, int, int, int]:
    """``rect=(x0, y0, w, h)`` checked against the image: pixels ``x0..x0+w-1`` etc."""
    if rect is None:
        return 0, 0, width, height
    try:
        vals = [v for v in rect]
    except TypeError:
        vals = []
    if len(vals) != 4 or any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in vals):
        raise ParameterError(f"rect: expected four integers (x0, y0, width, height), got {rect!r}")
    x0, y0, w, h = (int(v) for v in vals)
    if x0 < 0 or y0 < 0 or w < 1 or h < 1 or x0 + w > width or y0 + h > height:
        raise ParameterError(
            f"rect: ({x0}, {y0}, {w}, {h}) is not inside the {width}x{height} image; expected "
            "0 <= x0, 0 <= y0, width, height >= 1, x0 + width <= image width, y0 + height <= image height"
        )
    return x0, y0, w, h


def initial_rgba(initial, w: int, h: int) -> np.ndarray:
    """``initial=`` as (h, w, 4) float32 premultiplied RGBA, or an empty (0, 0, 4) array."""
    if initial is None:
        return np.zeros((0, 0, 4), np.float32)
    arr = np.ascontiguousarray(initial, dtype=np.float32)
    if arr.shape != (h, w, 4):
        raise ParameterError(f"initial: expected premultiplied RGBA of shape ({h}, {w}, 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)) or arr.min(initial=0.0) < 0 or arr.max(initial=0.0) > 1:
        raise ParameterError("initial: expected finite premultiplied RGBA in [0, 1]")
    return arr


def world_clip(clip_box, clip_open) -> tuple[np.ndarray, np.ndarray] | None:
    """``clip_box=`` and ``clip_open=`` checked: ``(box (2, 3) float64 world lower/upper
    corners, open (2, 3) bool faces)``, or None without a clip box."""
    if clip_box is None:
        if clip_open is not None:
            raise ParameterError("clip_open: applies only with clip_box")
        return None
    try:
        box = np.array(clip_box, dtype=np.float64)
    except (TypeError, ValueError):
        box = np.zeros(0)
    if box.shape != (2, 3) or not np.all(np.isfinite(box)) or np.any(box[0] > box[1]):
        raise ParameterError(
            f"clip_box: expected ((x0, y0, z0), (x1, y1, z1)) of finite world coordinates with x0 <= x1 "
            f"etc., got {clip_box!r}"
        )
    flags = np.zeros((2, 3), np.bool_) if clip_open is None else np.asarray(clip_open)
    if flags.shape != (2, 3) or flags.dtype != np.bool_:
        raise ParameterError(f"clip_open: expected ((bool, bool, bool), (bool, bool, bool)), got {clip_open!r}")
    return box, flags
