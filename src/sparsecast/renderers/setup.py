"""Per-frame render set-up shared by all marchers, and the marcher registry."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["RenderSetup", "register_marcher", "marcher_for"]


@dataclass
class RenderSetup:
    """Everything a marcher kernel needs for one frame, as arrays and scalars.

    The three output arrays are allocated by :func:`sparsecast.render` and filled
    by the marcher: ``rgba`` (H, W, 4) float32 premultiplied, ``samples`` and
    ``nonempty`` (H, W) int32 per-pixel counts of samples taken and of samples
    with non-zero opacity.
    """

    width: int
    height: int
    cam: np.ndarray          # Camera.ray_params
    table: np.ndarray        # (n, 4) float32, step-corrected opacity
    v_lo: float
    scale: float
    origin: np.ndarray       # (3,) float64, world position of voxel (0, 0, 0)
    inv_spacing: np.ndarray  # (3,) float64
    dt: float
    ert: float
    shading: np.ndarray      # (5,) float64, see kernels.shade
    background: np.ndarray   # (4,) float64 straight RGBA
    rgba: np.ndarray
    samples: np.ndarray
    nonempty: np.ndarray


Marcher = Callable[[object, RenderSetup], None]
_MARCHERS: dict[str, Marcher] = {}


def register_marcher(index_name: str) -> Callable[[Marcher], Marcher]:
    """Decorator: the function that renders indices named ``index_name``."""

    def deco(fn: Marcher) -> Marcher:
        _MARCHERS[index_name] = fn
        return fn

    return deco


def marcher_for(index_name: str) -> Marcher:
    try:
        return _MARCHERS[index_name]
    except KeyError:
        raise NotImplementedError(f"no renderer registered for index {index_name!r}") from None
