"""What every spatial index is: an immutable object built from a volume and a TF."""

from __future__ import annotations

from typing import Any, ClassVar, NamedTuple

import numpy as np

from ..transfer import TransferFunction
from ..volume import Volume

__all__ = ["SpatialIndex", "View"]


class View(NamedTuple):
    """What an index may need of the camera to prepare a frame's traversal record.

    Attributes
    ----------
    eye : (3,) float64
        Eye position in index space (perspective cameras).
    direction : (3,) float64
        View direction in index space (not normalised; orthographic cameras).
    perspective : bool
    """

    eye: np.ndarray
    direction: np.ndarray
    perspective: bool


class SpatialIndex:
    """Base class of the empty-space-skipping indices.

    Subclasses set :attr:`name`, build themselves in ``__init__`` and record the
    time of each build phase in ``self.build_phases`` (milliseconds) and their
    memory in ``self.nbytes``. A renderer reads an index only through the arrays
    its class documents; a TF change means building a new index (per-volume
    precomputation such as :meth:`Volume.brick_stats` is cached on the volume).

    The DVR driver reaches an index only through :meth:`traversal_record`: a
    ``NamedTuple`` of arrays whose class has ``start_ray`` / ``next_interval``
    overloads (see :mod:`sparsecast.index.interval`).
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
        #: first-use kernel compilation (or cache load) before the build, set by
        #: build_index and kept out of build_ms (see index.warm)
        self.compile_ms: float = 0.0
        #: set by build_index(name="auto"): occupancy, editing, reason of the choice
        self.auto: dict | None = None

    def traversal_record(self, view: View) -> tuple:
        """The record the driver traverses for one frame seen from ``view``.

        Most indices return the same record every frame; view-dependent ones
        (a leaf list sorted front to back) build it here. Never mutates the index.
        """
        raise NotImplementedError(f"{type(self).__name__} has no traversal record")

    @property
    def build_ms(self) -> float:
        return float(sum(self.build_phases.values()))

    def stats(self) -> dict[str, Any]:
        """Sizes and build times: at least ``index``, ``build_ms``, ``phases`` and ``bytes``."""
        return {
            "index": self.name,
            "build_ms": self.build_ms,
            "compile_ms": self.compile_ms,
            "phases": dict(self.build_phases),
            "bytes": int(self.nbytes),
        }

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} build={self.build_ms:.2f} ms bytes={self.nbytes}>"
