"""Rendering: the one DVR driver and its ``render()`` entry point; particles."""

from ..image import Image
from .api import DEFAULT_SHADING, render

__all__ = ["render", "Image", "DEFAULT_SHADING"]
