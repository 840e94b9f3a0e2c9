"""The :class:`Image` a render returns: premultiplied float RGBA plus statistics."""

from __future__ import annotations

import io as _io
import os
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ParameterError
from ._util.atomic import atomic_path

__all__ = ["Image", "IMAGE_SUFFIXES"]

_PIL_SUFFIXES = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp"}
#: every suffix :meth:`Image.save` writes
IMAGE_SUFFIXES = frozenset(_PIL_SUFFIXES | {".npy"})


class Image:
    """A rendered frame.

    Attributes
    ----------
    rgba : ndarray, shape (H, W, 4), float32
        Premultiplied colour and opacity in ``[0, 1]``; row 0 is the top of the image.
    stats : dict
        At least ``ms`` (render wall time), ``samples`` (volume samples taken),
        ``rays`` (primary rays), plus ``samples_nonempty`` (samples with non-zero
        opacity: the minimum any exact empty-space skipper must take, before early
        termination) and the parameters of the frame.
    samples : ndarray, shape (H, W), int32
        Samples taken per pixel (a cost heat map).
    """

    def __init__(self, rgba: np.ndarray, stats: dict[str, Any] | None = None,
                 samples: np.ndarray | None = None) -> None:
        rgba = np.asarray(rgba, dtype=np.float32)
        if rgba.ndim != 3 or rgba.shape[2] != 4:
            raise ParameterError(f"rgba: expected shape (H, W, 4), got {rgba.shape}")
        self.rgba = rgba
        self.stats = dict(stats or {})
        self.samples = samples

    @property
    def width(self) -> int:
        return int(self.rgba.shape[1])

    @property
    def height(self) -> int:
        return int(self.rgba.shape[0])

    def to_uint8(self) -> np.ndarray:
        """Straight-alpha 8-bit RGBA, as image files store it."""
        a = self.rgba[..., 3:4]
        rgb = np.divide(self.rgba[..., :3], a, out=np.zeros_like(self.rgba[..., :3]), where=a > 0)
        straight = np.concatenate([rgb, a], axis=-1)
        return np.clip(np.rint(straight * 255.0), 0, 255).astype(np.uint8)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the image atomically.

        ``.png`` (and other Pillow formats) store 8-bit straight RGBA (JPEG and BMP
        drop alpha); ``.npy`` stores the float32 premultiplied array unchanged. A
        symlink is written through (its target is replaced); a failed write (disk
        full, read-only) raises FileFormatError and leaves no partial file.
        """
        p = Path(path)
        suffix = p.suffix.lower()
        if suffix == ".npy":
            with atomic_path(p) as tmp:
                np.save(tmp, self.rgba)
            return p
        if suffix not in _PIL_SUFFIXES:
            raise ParameterError(
                f"output {str(p)!r}: unsupported image suffix {suffix!r}; expected .npy or one of "
                + ", ".join(sorted(_PIL_SUFFIXES))
            )
        from PIL import Image as PILImage

        pil = PILImage.fromarray(self.to_uint8())
        if suffix in {".jpg", ".jpeg", ".bmp"}:
            pil = pil.convert("RGB")
        with atomic_path(p) as tmp:
            pil.save(tmp)
        return p

    def _repr_png_(self) -> bytes:
        """Lets Jupyter display an Image inline."""
        from PIL import Image as PILImage

        buf = _io.BytesIO()
        PILImage.fromarray(self.to_uint8()).save(buf, format="PNG")
        return buf.getvalue()

    def __repr__(self) -> str:
        ms = self.stats.get("ms")
        ms_txt = f", {ms:.1f} ms" if isinstance(ms, (int, float)) else ""
        return f"<Image {self.width}x{self.height}{ms_txt}, {self.stats.get('samples', '?')} samples>"
