"""File-name rules shared by the volume formats: the format suffix and the stem without it."""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["suffix_of", "stem_of", "natural_key"]


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


def natural_key(p: Path) -> list:
    """Sort key of a file name in natural order: ``s2`` before ``s10`` (slices, time steps)."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", p.name)]
