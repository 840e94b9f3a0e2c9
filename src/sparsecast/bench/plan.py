"""The case plan of a benchmark run: every case key, listed once.

A case key (see :func:`~.progress.case_key`) names one measurement. The runner asks
the journal whether a key is done and records under that same key, and the progress
total counts these same keys, so each key is spelled here and nowhere else.
Cases, in run order, per dataset: ``load``, ``brick_stats``; per TF (the dataset's
own, then ``dense``): ``tf_classify``, then per method ``build_cold``, ``rebuild``
and one ``render`` per image size and view, then one ``render`` per peer, size and
peer view; after every dataset, one ``section_done`` per section.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from .suites import view_name

__all__ = ["Key", "CasePlan", "dataset_key", "classify_key", "build_key", "render_key", "section_key"]

#: the fields of one case key (a record holds them, plus its measurements)
Key = dict[str, Any]


def dataset_key(ds: str, phase: str) -> Key:
    """Per-dataset cases: ``load`` and ``brick_stats``."""
    return dict(dataset=ds, phase=phase)


def classify_key(ds: str, tf: str) -> Key:
    """Re-classifying every brick of ``ds`` for TF ``tf``."""
    return dict(dataset=ds, tf=tf, phase="tf_classify")


def build_key(ds: str, tf: str, method: str, phase: str) -> Key:
    """Index builds: ``build_cold`` (first build on a volume) and ``rebuild`` (a TF edit)."""
    return dict(dataset=ds, tf=tf, method=method, phase=phase)


def render_key(ds: str, tf: str, method: str, size: tuple[int, int], view: tuple[float, float]) -> Key:
    """One frame of ``method`` (an index spec or a peer) at ``size`` from ``view``."""
    w, h = size
    return dict(dataset=ds, tf=tf, method=method, width=w, height=h, view=view_name(view), phase="render")


def section_key(name: str, datasets: Sequence[str] = ()) -> Key:
    """The bookkeeping record that says section ``name`` finished (its records are journaled at once).

    ``datasets``: the names the section was given (none: its defaults), so that a run
    of the same section on other data in the same folder is a new case, not a resume.
    """
    key: Key = dict(method=name, phase="section_done")
    if datasets:
        key["dataset"] = ",".join(datasets)
    return key


@dataclass(frozen=True)
class CasePlan:
    """Which cases a run has: datasets x TFs x (methods + peers) x sizes x views, and sections.

    Attributes
    ----------
    datasets : list of str
        The datasets that are available (the others were skipped).
    tfs : list of str
        ``"default"`` (the dataset's own TF), and ``"dense"`` when the config asks.
    methods, peers, sections : list of str
        Index specs, peers that loaded, sections that exist.
    sizes : list of (width, height)
    views : list of (azimuth, elevation)
    dense_views : int or None
        The dense TF renders only the first this many views (None: all).
    peer_views : int
        Peers render the first this many views.
    section_data : dict of str to tuple of str
        The dataset names each section is given (a section not in it: its defaults).
    """

    datasets: list[str]
    tfs: list[str]
    methods: list[str]
    peers: list[str]
    sections: list[str]
    sizes: list[tuple[int, int]]
    views: list[tuple[float, float]]
    dense_views: int | None
    peer_views: int
    section_data: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def section_key(self, name: str) -> Key:
        """The marker key of section ``name`` with the datasets it is given."""
        return section_key(name, self.section_data.get(name, ()))

    def views_for(self, tf: str, peer: bool = False) -> list[tuple[float, float]]:
        """The views rendered for TF ``tf`` (by our methods, or by the peers)."""
        views = self.views
        if tf == "dense" and self.dense_views is not None:
            views = views[: self.dense_views]
        return views[: self.peer_views] if peer else views

    def render_keys(self, ds: str, tf: str, method: str, peer: bool = False) -> list[Key]:
        return [render_key(ds, tf, method, size, v) for size in self.sizes for v in self.views_for(tf, peer)]

    def method_keys(self, ds: str, tf: str, spec: str) -> list[Key]:
        return ([build_key(ds, tf, spec, p) for p in ("build_cold", "rebuild")]
                + self.render_keys(ds, tf, spec))

    def tf_keys(self, ds: str, tf: str) -> list[Key]:
        keys = [classify_key(ds, tf)]
        for spec in self.methods:
            keys += self.method_keys(ds, tf, spec)
        for peer in self.peers:
            keys += self.render_keys(ds, tf, peer, peer=True)
        return keys

    def dataset_keys(self, ds: str) -> list[Key]:
        keys = [dataset_key(ds, p) for p in ("load", "brick_stats")]
        for tf in self.tfs:
            keys += self.tf_keys(ds, tf)
        return keys

    def keys(self) -> list[Key]:
        """Every case of the run, in run order."""
        return [k for ds in self.datasets for k in self.dataset_keys(ds)] + [self.section_key(s) for s in self.sections]
