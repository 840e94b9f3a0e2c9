"""Images a benchmark keeps: PSNR against a reference and PNGs for a person to compare."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .._util.atomic import atomic_path

__all__ = ["psnr", "save_png", "image_name"]


def psnr(image: np.ndarray, reference: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB of two RGB(A) images with values in [0, 1].

    Compares the colour channels only (both composited over black, i.e. the
    premultiplied RGB); ``inf`` when they are identical.
    """
    a = np.asarray(image, np.float64)[..., :3]
    b = np.asarray(reference, np.float64)[..., :3]
    if a.shape != b.shape:
        raise ValueError(f"psnr: image shapes differ, {a.shape} vs {b.shape}")
    mse = float(np.mean((a - b) ** 2))
    return float("inf") if mse == 0.0 else float(10.0 * np.log10(1.0 / mse))


def save_png(rgb: np.ndarray, path: Path) -> Path:
    """Write an (H, W, 3|4) float image in [0, 1] (premultiplied colour over black) as
    an 8-bit RGB PNG, atomically."""
    from PIL import Image as PILImage

    u8 = np.clip(np.rint(np.asarray(rgb)[..., :3] * 255.0), 0, 255).astype(np.uint8)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        PILImage.fromarray(u8).save(tmp)
    return path


def image_name(*parts: object) -> str:
    """A file name built from case fields (safe characters only), e.g.
    ``demo_default_512x512_az30_el20_vtk.png``."""
    text = "_".join(str(p) for p in parts if p is not None)
    return re.sub(r"[^A-Za-z0-9._=-]+", "-", text) + ".png"
