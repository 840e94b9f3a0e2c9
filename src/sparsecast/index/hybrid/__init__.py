"""``hybrid-pc`` / ``hybrid-mm``: a shallow k-d tree with a macrocell grid inside each leaf."""

from .build import HYBRID_CELL, HybridMinMax, HybridPreclassified
from .traversal import HybridRecord

__all__ = ["HybridPreclassified", "HybridMinMax", "HYBRID_CELL", "HybridRecord"]
