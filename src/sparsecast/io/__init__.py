"""File input and output: volumes, images (and later meshes)."""

from .volumes import load_volume, parse_raw_name, save_volume

__all__ = ["load_volume", "save_volume", "parse_raw_name"]
