"""Benchmark section ``features``: what hiding labels, clipping, isosurfaces and shading cost.

Four cases, each timed in interleaved rounds (:func:`.timing.interleaved`: every
variant renders one frame per round, in turn, after a warm-up round) with the same
index, camera and image, and each variant's image compared with naive's (the
``max_abs_diff`` of an exact method is at most 1e-5):

- ``labels``: a generated segmentation (:func:`label_scene`: 16 labelled spheres in
  160^3, the 8 largest covering most non-empty bricks); ``all`` shown vs ``half``
  hidden (the largest 8), the index rebuilt for each TF (``build_ms``);
  ``speedup`` = all / half.
- ``clip``: every CT / MR volume of the shared data with its benchmark TF, unclipped
  vs a clip box keeping the half ``x <= centre`` (``half-box``) and vs an oblique
  clip plane through the centre (``half-plane``, normal :data:`PLANE_NORMAL`), for
  each of :data:`CLIP_INDICES`; ``speedup`` = unclipped / clipped of the same index,
  ``sample_ratio`` = unclipped / clipped samples (the speed-up a per-sample cost alone
  would give).
- ``iso``: the same volumes, an isosurface at 35 % of the value range; ``naive`` vs
  the exact indices (``kdtree-deep``, ``grid-pc``, ``lbvh``); ``speedup`` = naive / ESS.
- ``shading``: the same volumes, DVR ``shaded`` (Blinn-Phong on the central-difference
  gradient, :data:`~sparsecast.render.options.DEFAULT_SHADING`) vs ``unshaded``, with
  the benchmark TF (``tf="default"``) for each of :data:`SHADING_INDICES` and with a TF
  that leaves nothing empty (``tf="dense"``: every sample classified and shaded) for
  naive; ``speedup`` on the ``unshaded`` row = shaded / unshaded, the cost of shading.

Records: ``phase="render"``, ``case``, ``variant``, the timing fields of
:meth:`.timing.Runs.fields` (median, raw runs, min/max, MAD, CPU ms, cores busy),
``samples``, ``speedup`` and ``sample_ratio`` (the case's base samples / the variant's).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..camera import Camera
from ..index import build_index
from ..render import render
from ..transfer import TransferFunction
from ..volume import Volume
from .catalog import DATASETS, dense_tf
from .timing import interleaved

__all__ = ["run", "CT_MR", "DATASET_NAMES", "CLIP_INDICES", "ISO_INDICES", "SHADING_INDICES", "label_scene"]

#: the shared CT / MR volumes of the clip and iso cases (skipped when absent)
CT_MR = ("bonsai", "tooth", "avm-cta", "chest-ct", "headsq", "mni152")
#: the volumes ``--dataset`` may name for this section (``sparsecast bench --suite features -d tooth``)
DATASET_NAMES = tuple(DATASETS)
#: the indices the clip case times clipped against unclipped: the k-d tree, and the
#: naive marcher (whose samples fall with the clipped length of each ray, the most a
#: clip can save; an index's samples fall by less where the cut keeps its non-empty part)
CLIP_INDICES = ("kdtree-deep", "naive")
#: the exact indices the iso case times against naive
ISO_INDICES = ("kdtree-deep", "grid-pc", "lbvh")
#: the indices the shading case times shaded vs unshaded with the benchmark TF (the
#: dense TF: naive alone, which every index matches there)
SHADING_INDICES = ("naive", "kdtree-deep")
VIEW = (30.0, 20.0)
#: the clip case's plane keeps the side this normal points to (away from the camera's side)
PLANE_NORMAL = (-1.0, 0.35, 0.2)


def label_scene(n: int = 160, labels: int = 16, seed: int = 7) -> tuple[Volume, dict[int, tuple]]:
    """Spheres of ids ``1..labels`` on background 0 (radii 6 % to 20 % of ``n``), and an
    opaque-ish colour per id (ids sorted by size: 1 is the largest)."""
    rng = np.random.default_rng(seed)
    z, y, x = np.ogrid[:n, :n, :n]
    data = np.zeros((n, n, n), np.uint8)
    radii = np.sort(rng.uniform(0.06, 0.2, labels))[::-1] * n
    for i, r in enumerate(radii, start=1):
        c = rng.uniform(r, n - r, 3)
        data[(x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2 <= r * r] = i
    colours = {i: (*tuple(rng.uniform(0.2, 1.0, 3)), 0.6) for i in range(1, labels + 1)}
    return Volume(data, name=f"labels-{n}"), colours


def run(datasets: list[str] | None, *, width: int, height: int, repeat: int, warmup: int,
        record: Callable[..., None], label_size: int = 160) -> None:
    """Measure the four cases (see the module docstring); ``datasets`` replaces
    :data:`CT_MR` for the clip, iso and shading cases, ``label_size`` the segmentation's edge."""
    _labels(width, height, repeat, warmup, record, label_size)
    for name in CT_MR if datasets is None else datasets:
        ds = DATASETS.get(name)
        if ds is None or not ds.available():
            record(dataset=name, method="features", phase="skipped", reason="dataset not available")
            continue
        vol = ds.load()
        tf = ds.make_tf(vol)
        _clip(name, vol, tf, width, height, repeat, warmup, record)
        _iso(name, vol, tf, width, height, repeat, warmup, record)
        _shading(name, vol, tf, width, height, repeat, warmup, record)


def _frames(variants: dict[str, Callable], repeat: int, warmup: int):
    """Interleaved runs of ``variants`` (name -> render call returning an Image)."""
    return interleaved({k: (lambda f=f: (lambda img: (img, img.stats["ms"]))(f())) for k, f in variants.items()},
                       repeat, warmup)


def _emit(record, common: dict, runs, reference, base: str) -> None:
    base_ms = runs[base].fields()["ms"]
    base_samples = runs[base].result.stats["samples"]
    for variant, r in runs.items():
        f = r.fields()
        img = r.result
        samples = img.stats["samples"]
        record(**common, variant=variant, method=img.stats["index"], phase="render", samples=samples,
               speedup=base_ms / f["ms"] if variant != base else 1.0,
               sample_ratio=base_samples / samples if samples else None,
               max_abs_diff=None if reference is None else float(np.abs(img.rgba - reference[variant]).max()),
               **f)


def _labels(width, height, repeat, warmup, record, n: int) -> None:
    vol, colours = label_scene(n)
    all_tf = TransferFunction.labels(colours, name="labels-all")
    half_tf = all_tf.hidden(range(1, 9))
    cam = Camera.orbit(vol, *VIEW)
    index = "kdtree-deep"
    built = {}
    for key, tf in (("all", all_tf), ("half", half_tf)):
        idx = build_index(vol, tf, index)
        built[key] = (tf, idx)
        record(dataset=vol.name, case="labels", variant=key, method=index, phase="rebuild", ms=idx.build_ms)
    variants = {k: (lambda tf=tf, idx=idx: render(vol, tf, cam, width, height, index=idx))
                for k, (tf, idx) in built.items()}
    runs = _frames(variants, repeat, warmup)
    reference = {k: render(vol, tf, cam, width, height, index="naive").rgba for k, (tf, _) in built.items()}
    _emit(record, dict(dataset=vol.name, case="labels", width=width, height=height), runs, reference, "all")


def _clip(name, vol, tf, width, height, repeat, warmup, record) -> None:
    cam = Camera.orbit(vol, *VIEW)
    lo, hi = vol.bounds
    box = (tuple(lo), (float(vol.center[0]), float(hi[1]), float(hi[2])))
    # An oblique plane through the centre: the planes are culled and clipped by other
    # code than the box (a half-space per node corner, an interval per ray).
    plane = [(tuple(float(c) for c in vol.center), PLANE_NORMAL)]
    clips = {"unclipped": {}, "half-box": {"clip_box": box}, "half-plane": {"clip_planes": plane}}
    reference = {k: render(vol, tf, cam, width, height, index="naive", **kw).rgba for k, kw in clips.items()}
    for method in CLIP_INDICES:
        index = build_index(vol, tf, method)
        variants = {k: (lambda kw=kw, index=index: render(vol, tf, cam, width, height, index=index, **kw))
                    for k, kw in clips.items()}
        runs = _frames(variants, repeat, warmup)
        _emit(record, dict(dataset=name, case="clip", width=width, height=height), runs, reference, "unclipped")


def _iso(name, vol, tf, width, height, repeat, warmup, record) -> None:
    cam = Camera.orbit(vol, *VIEW)
    lo, hi = vol.value_range
    iso = lo + 0.35 * (hi - lo)
    variants = {"naive": lambda: render(vol, tf, cam, width, height, index="naive", mode="iso", iso=iso)}
    for index in ISO_INDICES:
        variants[index] = lambda index=index: render(vol, tf, cam, width, height, index=index, mode="iso", iso=iso)
    runs = _frames(variants, repeat, warmup)
    ref = runs["naive"].result.rgba
    _emit(record, dict(dataset=name, case="iso", iso=iso, width=width, height=height), runs,
          {k: ref for k in variants}, "naive")


def _shading(name, vol, tf, width, height, repeat, warmup, record) -> None:
    cam = Camera.orbit(vol, *VIEW)
    cases = [("default", tf, index) for index in SHADING_INDICES] + [("dense", dense_tf(vol), "naive")]
    for tf_name, t, index in cases:
        idx = build_index(vol, t, index)
        variants = {k: (lambda on=on: render(vol, t, cam, width, height, index=idx, shading=on))
                    for k, on in (("shaded", True), ("unshaded", False))}
        runs = _frames(variants, repeat, warmup)
        if index == "naive":
            reference = {k: r.result.rgba for k, r in runs.items()}
        else:
            reference = {k: render(vol, t, cam, width, height, index="naive", shading=k == "shaded").rgba
                         for k in variants}
        # Base "shaded": the unshaded row's speed-up is shaded / unshaded ms, what shading costs.
        _emit(record, dict(dataset=name, case="shading", tf=tf_name, width=width, height=height), runs,
              reference, "shaded")
