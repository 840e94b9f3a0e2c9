"""What every spatial index is: an immutable object built from a volume and a TF."""

from __future__ import annotations

from typing import Any, ClassVar

from ..transfer import TransferFunction
from ..volume import Volume

__all__ = ["SpatialIndex"]


class SpatialIndex:
    """Base class of the empty-space-skipping indices.

    Subclasses set :attr:`name`, build themselves in ``__init__`` and record the
    time of each build phase in ``self.build_phases`` (milliseconds) and their
    memory in ``self.nbytes``. A renderer reads an index only through the arrays
    its class documents; a TF change means building a new index (per-volume
    precomputation such as :meth:`Volume.brick_stats` is cached on the volume).
    """

    #: name accepted by ``build_index`` / ``render(index=...)``
    name: ClassVar[str] = ""
    #: whether images equal the naive marcher's (exact ESS) or approximate it
    exact: ClassVar[bool] = True

    def __init__(self, volume: Volume, tf: TransferFunction) -> None:
        self.volume = volume
        self.tf = tf
        self.build_phases: dict[str, float] = {}
        self.nbytes: int = 0

    @property
    def build_ms(self) -> float:
        return float(sum(self.build_phases.values()))

    def stats(self) -> dict[str, Any]:
        """Sizes and build times: at least ``index``, ``build_ms``, ``phases`` and ``bytes``."""
        return {
            "index": self.name,
            "build_ms": self.build_ms,
            "phases": dict(self.build_phases),
            "bytes": int(self.nbytes),
        }

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} build={self.build_ms:.2f} ms bytes={self.nbytes}>"
