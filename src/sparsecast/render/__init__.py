"""Rendering: the one DVR driver and its ``render()`` entry point; particles."""

from ..image import Image
from .api import DEFAULT_SHADING, classification_tf, render, same_emptiness

__all__ = ["render", "classification_tf", "same_emptiness", "Image", "DEFAULT_SHADING"]
