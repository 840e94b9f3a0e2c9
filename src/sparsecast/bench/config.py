"""What a benchmark run measures: :class:`BenchConfig` (a suite's plan, plus overrides)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..index import available_indices
from .catalog import DATASETS
from .suites import Suite

__all__ = ["BenchConfig"]


@dataclass
class BenchConfig:
    """What ``sparsecast bench`` runs.

    Attributes
    ----------
    datasets : list of str
        Names from :data:`DATASETS`; unavailable ones (no shared data) are skipped.
    methods : list of str
        Index names (see :func:`available_indices`), optionally with build options
        as ``name:key=value,...`` (e.g. ``grid-pc:cell=8``).
    sizes : list of (width, height)
        Image sizes.
    views : list of (azimuth, elevation)
        Orbit views, in degrees.
    projection : str
    repeat : int
        Timed runs per measurement (the median is reported).
    warmup : int
        Untimed runs before timing (JIT compilation, caches).
    dt : float or None
        Sampling step (default: half the smallest spacing).
    dense_tf : bool
        Also run every method with a TF that leaves no empty space.
    irt : bool
        Also time iterative-range-tree builds and queries on TF tables of 256-4096
        entries against the prefix-count query.
    peers : list of str
        Peer renderers (``vtk``, ``yt``) run on the same cases; missing ones are skipped.
    dense_views : int or None
        The dense TF renders only the first this many views (None: all): with no
        empty space every index costs about a naive frame, and a few views show it.
    peer_views : int
        Peers render the first this many views (they are much slower than the indices).
    sections : list of str
        ``sparsecast.bench.<name>`` modules whose ``run(...)`` adds their own tables.
    images_dir : path or None
        Where to save our (naive) image and each peer's image of the first view per
        size, for a person to compare.
    section_datasets : list of str
        Names given as datasets that a section knows rather than :data:`DATASETS`
        (the surface section's meshes, e.g. ``dragon``): see :meth:`route_datasets`.
    section_only : bool
        The run is its sections alone (a suite such as ``features`` or ``surface``,
        which names no volumes of its own): a dataset name a section knows goes to
        the section only, even where it is a volume of :data:`DATASETS` too.
    """

    datasets: list[str] = field(default_factory=lambda: [n for n, d in DATASETS.items() if d.default])
    methods: list[str] = field(default_factory=available_indices)
    sizes: list[tuple[int, int]] = field(default_factory=lambda: [(512, 512)])
    views: list[tuple[float, float]] = field(default_factory=lambda: [(30.0, 20.0), (0.0, 0.0)])
    projection: str = "perspective"
    repeat: int = 5
    warmup: int = 1
    dt: float | None = None
    dense_tf: bool = True
    irt: bool = True
    peers: list[str] = field(default_factory=list)
    dense_views: int | None = None
    peer_views: int = 2
    sections: list[str] = field(default_factory=list)
    images_dir: Path | None = None
    section_datasets: list[str] = field(default_factory=list)
    section_only: bool = False

    def route_datasets(self) -> list[str]:
        """Move the dataset names a section of this run knows (its module's
        ``DATASET_NAMES``) and :data:`DATASETS` does not to :attr:`section_datasets`;
        with :attr:`section_only`, every name a section knows (``--suite features -d
        tooth`` measures the features on the tooth, not every index on it as well).

        Returns the names neither knows, for the caller to report.
        """
        known = {n for s in self.sections for n in section_dataset_names(s)}
        volumes, unknown = [], []
        for n in self.datasets:
            if n in known and (self.section_only or n not in DATASETS):
                if n not in self.section_datasets:
                    self.section_datasets.append(n)
            elif n in DATASETS:
                volumes.append(n)
            else:
                unknown.append(n)
        self.datasets = volumes
        return unknown

    @classmethod
    def from_suite(cls, suite: Suite, **overrides: Any) -> "BenchConfig":
        """The config of ``suite``; keyword arguments that are not None replace its fields."""
        cfg = cls(
            datasets=suite.dataset_names(),
            methods=suite.method_specs(),
            sizes=list(suite.sizes), views=list(suite.views), repeat=suite.repeat, warmup=suite.warmup,
            dense_tf=suite.dense_tf, dense_views=suite.dense_views, peer_views=suite.peer_views,
            irt=suite.irt, peers=list(suite.peers), sections=list(suite.sections),
            section_only=suite.datasets == () and bool(suite.sections),
        )
        for key, value in overrides.items():
            if value is not None:
                setattr(cfg, key, value)
        return cfg


def section_dataset_names(section: str) -> tuple[str, ...]:
    """The dataset names ``sparsecast.bench.<section>`` takes (its ``DATASET_NAMES``;
    none for a section that has no such list or is not there)."""
    import importlib
    import importlib.util

    name = f"{__package__}.{section}"
    if not section.isidentifier() or importlib.util.find_spec(name) is None:
        return ()
    return tuple(getattr(importlib.import_module(name), "DATASET_NAMES", ()))
