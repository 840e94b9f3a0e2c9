"""File-name rules shared by the volume formats: the format suffix and the stem without it."""

from __future__ import annotations

from pathlib import Path

__all__ = ["suffix_of", "stem_of"]


def suffix_of(path: Path) -> str:
    """Lower-case format suffix, with ``.nii.gz`` treated as one suffix."""
    name = path.name.lower()
    if name.endswith(".nii.gz"):
        return ".nii.gz"
    return path.suffix.lower()


def stem_of(path: Path) -> str:
    """File name without its format suffix (``brain.nii.gz`` -> ``brain``)."""
    suffix = suffix_of(path)
    if suffix and path.name.lower().endswith(suffix):
        return path.name[: len(path.name) - len(suffix)] or path.name
    return path.stem or path.name
