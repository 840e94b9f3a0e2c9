"""``bih``: bounding interval hierarchy over elements (exact ESS, BIH-DVR, particles)."""

from .build import BIH, LAYOUTS, MODES, VARIANTS, BIHTree, PackedBIH, ParticleBIH, build_bih, element_tree
from .traversal import BihApproxRecord, BihRecord

__all__ = ["BIH", "BIHTree", "PackedBIH", "ParticleBIH", "build_bih", "element_tree", "BihRecord",
           "BihApproxRecord", "MODES", "VARIANTS", "LAYOUTS"]
