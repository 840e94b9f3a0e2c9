"""``naive``: one interval per ray, the whole clip box (the reference)."""

from .build import NaiveIndex
from .traversal import NaiveRecord

__all__ = ["NaiveIndex", "NaiveRecord"]
