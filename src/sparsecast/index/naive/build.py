"""The trivial index: no skipping at all. The reference every ESS index must match."""

from __future__ import annotations

from ..base import SpatialIndex, View
from ..registry import register_index
from .traversal import NaiveRecord


@register_index
class NaiveIndex(SpatialIndex):
    """Marches every lattice sample inside the volume box; builds in no time."""

    name = "naive"

    def __init__(self, volume, tf) -> None:
        super().__init__(volume, tf)
        self.build_phases = {"build": 0.0}

    def traversal_record(self, view: View) -> NaiveRecord:
        return NaiveRecord()
