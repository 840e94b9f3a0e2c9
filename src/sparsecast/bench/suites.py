"""Benchmark suites as data: datasets x methods x image sizes x views x TFs.

- ``quick``: the everyday run (what a plain ``sparsecast bench`` does), about a
  minute on two cores (each suite's measured ``duration`` is kept on it).
- ``paper``: the papers' evaluation: every shared volume and the generated n-body
  fields at 128^3 / 256^3 / 512^3, every registered index, 512^2 and 1024^2, one
  view on each of the orbits around the three axes, sparse and dense TF, the
  installed peers (VTK, yt, pyvista's GPU mapper) and the sections of the other
  modules (``bih``, ``surface``).

Every suite times each view in at least 3 interleaved rounds after a warm-up round
(see :func:`~.timing.interleaved`).
- ``sweep``: the synthetic cluster sweeps (hybrid-grids paper, Fig. 5) at 256^3.
- ``bih`` / ``surface``: one section on its own.

Suites can share one output: records of every suite run into the same journal
end up in the same report.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import ParameterError
from .catalog import DATASETS

__all__ = ["Suite", "SUITES", "orbit_views", "get_suite", "view_name", "every_method", "suites_help"]


def orbit_views(steps: int) -> list[tuple[float, float]]:
    """Views orbiting the volume in ``steps`` equal steps around each of the three axes.

    Returns ``(azimuth, elevation)`` pairs for :meth:`Camera.orbit` (degrees):
    around z the azimuth turns at elevation 0; around x the elevation turns at
    azimuth 0 (the eye moves in the y-z plane); around y the elevation turns at
    azimuth 90 (x-z plane). The angles start a quarter step in, so that the
    circles do not meet on the axes, and a view whose eye direction an earlier one
    already has is left out.
    """
    if steps < 1:
        raise ParameterError(f"steps: expected at least 1 view per axis, got {steps}")
    step = 360.0 / steps
    angles = [round((i + 0.25) * step, 6) for i in range(steps)]
    views: list[tuple[float, float]] = []
    seen: set[tuple[float, ...]] = set()
    for az, el in [(a, 0.0) for a in angles] + [(0.0, a) for a in angles] + [(90.0, a) for a in angles]:
        a, e = np.radians(az), np.radians(el)
        # Camera.orbit's direction from the centre to the eye
        eye = (-np.sin(a) * np.cos(e), -np.cos(a) * np.cos(e), np.sin(e))
        key = tuple(np.round(eye, 6) + 0.0)  # + 0.0: -0.0 and 0.0 are one direction
        if key not in seen:
            seen.add(key)
            views.append((az, el))
    return views


def view_name(view: tuple[float, float]) -> str:
    """The record label of a view, e.g. ``az30_el20``."""
    az, el = view
    return f"az{az:g}_el{el:g}"


@dataclass(frozen=True)
class Suite:
    """One benchmark plan.

    Attributes
    ----------
    name, description : str
    datasets : tuple of str or None
        Names from :data:`DATASETS`; ``None``: every dataset marked ``default``.
    methods : tuple of str or None
        Index specs (``name[:key=value,...]``); ``None``: every registered index,
        discovered at run time so new indices join without editing suites.
    index_modes : bool
        With ``methods=None``, also every index's other modes (:func:`every_method`).
    sizes : tuple of (width, height)
    views : tuple of (azimuth, elevation)
    dense_tf : bool
        Also run a TF with no empty space next to each dataset's sparse one.
    dense_views : int or None
        Views rendered with the dense TF (the first N; None: all).
    repeat, warmup : int
        Timed and untimed rounds per view: every method and peer renders one frame
        per round, in turn (at least 3 timed rounds and 1 warm-up in every suite;
        suites with a time budget take fewer views instead).
    irt : bool
        Time the iterative range tree on TF tables.
    peers : tuple of str
        Other renderers to run on the same cases (``vtk``, ``yt``, ``pyvista``); missing ones are skipped.
    peer_views : int
        Views the peers render (the first N).
    sections : tuple of str
        Modules ``sparsecast.bench.<name>`` with a ``run(...)`` of their own tables.
    short : str
        A few words for ``sparsecast bench --help``.
    duration : str or None
        Wall time of a whole run on the reference machine of the README's Performance
        section (2-core VM), as the README's suite table and ``--help`` print it;
        None where not measured. The one place these figures live. (Measured before
        the interleaved rounds of the timing: to be measured again.)
    """

    name: str
    description: str
    short: str = ""
    duration: str | None = None
    datasets: tuple[str, ...] | None = None
    methods: tuple[str, ...] | None = None
    index_modes: bool = False
    sizes: tuple[tuple[int, int], ...] = ((512, 512),)
    views: tuple[tuple[float, float], ...] = ((30.0, 20.0), (0.0, 0.0))
    dense_tf: bool = True
    dense_views: int | None = None
    repeat: int = 5
    warmup: int = 1
    irt: bool = True
    peers: tuple[str, ...] = ()
    peer_views: int = 2
    sections: tuple[str, ...] = ()

    def with_overrides(self, **changes) -> "Suite":
        """A copy with the given fields replaced (fields left as None are kept)."""
        return replace(self, **{k: v for k, v in changes.items() if v is not None})

    def method_specs(self) -> list[str]:
        if self.methods is not None:
            return list(self.methods)
        if self.index_modes:
            return every_method()
        from ..index import available_indices

        return available_indices()

    def dataset_names(self) -> list[str]:
        if self.datasets is not None:
            return list(self.datasets)
        return [n for n, d in DATASETS.items() if d.default]


def every_method() -> list[str]:
    """Every registered index, plus its other modes where it has them (the BIH's
    approximate ``single-sample`` / ``multi-sample`` rendering), as method specs."""
    from ..index import available_indices

    methods = available_indices()
    if "bih" in methods:
        from ..index import bih

        methods += [f"bih:mode={m}" for m in bih.MODES if m != "ess"]
    return methods


def _paper_datasets() -> tuple[str, ...]:
    shared = tuple(n for n, d in DATASETS.items() if d.file is not None)
    return shared + ("demo-128", "demo", "demo-512")


SUITES: dict[str, Suite] = {
    s.name: s
    for s in (
        # Three timed frames per view, and the dense TF (each index about a naive frame)
        # on one view, keep the everyday run under two minutes on two cores.
        Suite("quick", "the demo and MNI152 (other shared volumes: -d NAME, or --suite paper), 512^2, two views, "
              "every index",
              short="the default run", duration="70 s", repeat=3, dense_views=1),
        Suite(
            "paper",
            "every shared volume and the n-body fields at 128^3/256^3/512^3, every index, "
            "512^2 and 1024^2, one view on each orbit around x, y, z (3 timed rounds and a warm-up "
            "per view, interleaved), sparse + dense TF, peers, BIH and RBVH sections",
            short="the papers' evaluation",
            duration="70 min",
            datasets=_paper_datasets(),
            sizes=((512, 512), (1024, 1024)),
            # 70 min on a 2-core Intel Xeon (2026-12-06, peers included). Budget: 4 frames
            # (warm-up + 3 rounds) on 3 views cost what 1 frame on each of the 12 orbit views
            # did; one view per axis circle keeps the three orbits. The dense TF (every index
            # about a naive frame) and the peers 1 view.
            views=tuple(orbit_views(4)[::4]),
            index_modes=True,
            dense_views=1,
            peer_views=1,
            repeat=3,
            warmup=1,
            peers=("vtk", "yt", "pyvista"),
            sections=("bih", "surface"),
        ),
        # One view (not two) pays for the 3 interleaved rounds and the warm-up.
        Suite("sweep", "the synthetic cluster sweeps of Fig. 5 at 256^3 (a: growing radius, b: more clusters), "
              "one view, 3 timed rounds and a warm-up",
              short="Fig. 5 clusters", duration="28 s",
              datasets=tuple(n for n in DATASETS if n.startswith(("fig5a-256-", "fig5b-256-"))),
              views=((30.0, 20.0),), dense_tf=False, repeat=3, warmup=1, irt=False),
        Suite("bih", "the BIH section only (element rendering, single-sample BIH-DVR)", short="BIH section",
              datasets=(), irt=False, sections=("bih",)),
        Suite("surface", "the RBVH section only (approximate surface ray casting)", short="RBVH section",
              duration="2 min", datasets=(), irt=False, sections=("surface",)),
        Suite("features", "labels hidden vs shown, a half clip box, isosurfaces naive vs ESS, shaded vs "
              "unshaded DVR, on the shared CT/MR volumes (bench.features)", short="features section",
              duration="7 min", datasets=(), irt=False, sections=("features",)),
        Suite("distributed", "rendering on a Dask LocalCluster of 2 one-thread workers: a 512^3 float32 field "
              "cut into 1, 2 and 4 pieces against one process, interleaved: frame and TF-change latency, bytes "
              "moved, compositing ms vs image size, a model of N machines (bench.distributed)",
              short="distributed section", duration=None, datasets=(), irt=False, sizes=((512, 512),),
              sections=("distributed",)),
        # Each (size, kind) case is a fresh subprocess; 2048^3 (32 GB dense) only with
        # SPARSECAST_BENCH_SCALE_MAX=2048.
        Suite("scale", "volumes larger than memory: a generated n-body float32 field at 256^3/512^3/1024^3 as "
              "Zarr (lazy), .npy and raw, each in a fresh process: open, statistics, first build, rebuild, "
              "1024^2 frame per exact index, time to first image, peak RSS (bench.scale)",
              short="larger-than-memory section", duration=None, datasets=(), irt=False,
              sizes=((1024, 1024),), sections=("scale",)),
    )
}


def suites_help() -> str:
    """``quick (the default run, 70 s), paper (...), ...``: the suites as ``--suite``'s help lists them."""
    return ", ".join(f"{s.name} ({s.short}" + (f", {s.duration})" if s.duration else ")") for s in SUITES.values())


def get_suite(name: str) -> Suite:
    """The suite called ``name`` (one-line error naming the choices otherwise)."""
    try:
        return SUITES[name]
    except KeyError:
        raise ParameterError(f"--suite: unknown suite {name!r}; expected one of {', '.join(SUITES)}") from None
