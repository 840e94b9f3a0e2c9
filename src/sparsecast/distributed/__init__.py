"""Data-parallel rendering on a Dask cluster, exact against a single process.

``sc.render(volume, tf, camera, ..., client=client)`` cuts the volume into pieces on
brick boundaries (:mod:`.decompose`), keeps each piece resident on a worker
(:mod:`.piece`), renders each piece's screen rectangle on the global lattice and
composites the layers front to back (:mod:`.composite`) in a tree of tasks
(:mod:`.cluster`). See ``docs/architecture.md`` ("Pieces on a cluster").
"""

from .cluster import DEFAULT_TIMEOUT, ClusterVolume, connect, render_on_cluster
from .composite import Layer, over
from .decompose import PieceTree, decompose
from .screen import screen_rect

__all__ = ["ClusterVolume", "render_on_cluster", "connect", "DEFAULT_TIMEOUT", "Layer", "over", "PieceTree",
           "decompose", "screen_rect"]
