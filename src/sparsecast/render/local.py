"""The single-process frame: one volume, one index, the one driver over every tile.

:func:`sparsecast.render.api.render` is the public entry point (it documents every
parameter); it calls :func:`render_local` for a frame in this process, and a cluster
renders each piece of a volume with it (:mod:`sparsecast.distributed`)."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._util.checks import as_float, as_int, one_of
from ..camera import Camera
from ..errors import ParameterError
from ..image import Image
from ..index import SpatialIndex, View
from ..kernels.iso import MAX_ISOVALUES, Iso, IsoDvr
from ..kernels.march import Dvr
from ..kernels.sampler import sampler_for
from ..kernels.shade import SHADING_SIZE
from ..transfer import TransferFunction
from ..volume import Volume
from .driver import tiles_kernel
from .frame import Frame
from .reuse import index_for_frame, same_emptiness
from .schedule import run_tiles
from .options import (
    DEFAULT_SHADING, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, background_array, check_size, initial_rgba,
    rect_bounds, shading_array, world_clip,
)

__all__ = ["render_local", "classification_tf", "same_emptiness", "MAX_IMAGE_SIDE", "MAX_IMAGE_PIXELS", "MAX_SAMPLES_PER_RAY", "MAX_CLIP_PLANES", "MAX_SAMPLES_PER_IMAGE",
           "DEFAULT_SHADING"]

MAX_SAMPLES_PER_RAY = 1 << 22

#: default cap on the samples one image may take (``max_samples=``, 8.6e9): about a
#: minute on two cores at ~150 M samples/s, enough for 1024^2 pixels through a 2048^3
#: volume at half-voxel steps; a larger render asks for it explicitly
MAX_SAMPLES_PER_IMAGE = 1 << 33

#: clip planes a render takes at most
MAX_CLIP_PLANES = 6
#: what a render composites (``mode=``)
RENDER_MODES = ("dvr", "iso", "iso+dvr")
#: the BIH's build modes, which ``render(mode=...)`` passes on to ``index="bih"``
BIH_MODES = ("ess", "single-sample", "multi-sample")


def render_local(
    volume: Volume,
    tf: TransferFunction,
    camera: Camera,
    width: int = 512,
    height: int = 512,
    *,
    dt: float | None = None,
    index: str | SpatialIndex = "auto",
    ert: float = 0.99,
    shading: bool | Mapping[str, float] | None = None,
    background: str | Sequence[float] = "transparent",
    clip_box: Sequence[Sequence[float]] | None = None,
    clip_open: Sequence[Sequence[bool]] | None = None,
    clip_planes: Sequence[tuple[Sequence[float], Sequence[float]]] | None = None,
    clip_cap: bool = False,
    initial: np.ndarray | None = None,
    rect: Sequence[int] | None = None,
    max_samples: int = MAX_SAMPLES_PER_IMAGE,
    mode: str = "dvr",
    iso: float | Sequence[float] | None = None,
    iso_colors: Sequence[Sequence[float]] | None = None,
    **index_options: Any,
) -> Image:
    """One frame in this process: :func:`sparsecast.render.api.render` without ``client``
    (see it for the parameters, the result and the errors)."""
    if isinstance(volume, np.ndarray):
        volume = Volume(volume)
    if not isinstance(volume, Volume):
        raise ParameterError(f"volume: expected a sparsecast.Volume, got {type(volume).__name__}")
    volume.require_renderable()  # a one-voxel-thick volume would render empty from every view
    if not isinstance(tf, TransferFunction):
        raise ParameterError(f"tf: expected a sparsecast.TransferFunction, got {type(tf).__name__}")
    if mode in BIH_MODES:  # render(..., index="bih", mode="single-sample"): a build option of the BIH
        index_options["mode"] = mode
        mode = "dvr"
    mode_marker = iso_mode(mode, iso, iso_colors, tf)
    if shading is None:
        shading = mode != "dvr"  # surfaces need their normals; DVR is unshaded unless asked
    if not isinstance(camera, Camera):
        raise ParameterError(f"camera: expected a sparsecast.Camera, got {type(camera).__name__}")
    width, height = check_size(width, height)
    x0, y0, w, h = rect_bounds(rect, width, height)
    min_spacing = float(volume.spacing.min())
    if dt is None:
        dt = 0.5 * min_spacing
    dt = as_float(dt, "dt", 0.0, lo_open=True, expected="a positive world-space step")
    if volume.diagonal / dt > MAX_SAMPLES_PER_RAY:
        raise ParameterError(
            f"dt: {dt:g} would take {volume.diagonal / dt:.3g} samples per ray across the volume; "
            f"expected at most {MAX_SAMPLES_PER_RAY} (dt >= {volume.diagonal / MAX_SAMPLES_PER_RAY:.3g})"
        )
    max_samples = as_int(max_samples, "max_samples", lo=1)
    bound = float(w) * h * (volume.diagonal / dt + 1.0)
    if bound > max_samples:
        raise ParameterError(
            f"dt: {dt:g} at {w}x{h} pixels could take {bound:.3g} samples ({volume.diagonal / dt:.3g} per ray); "
            f"expected at most max_samples={max_samples:.3g}: use a larger dt (>= "
            f"{volume.diagonal * w * h / max_samples:.3g}), a smaller image, or raise max_samples"
        )
    ert = as_float(ert, "ert", 0.0, 1.0, lo_open=True, expected="an opacity threshold in (0, 1]")
    clip_lo, clip_hi, open_lo, open_hi = _clip(volume, clip_box, clip_open)
    cap = _cap_shading(clip_cap, mode, shading)
    init = initial_rgba(initial, w, h)

    # The iso modes skip bricks by a TF that is non-empty around the isovalues.
    classify = classification_tf(tf, mode, mode_marker.values) if mode != "dvr" else tf
    # A bricked volume makes what this frame can see resident before any index reads it.
    data = volume.voxels(classify, mode=mode)
    build_ms = 0.0
    build_jit_ms = 0.0
    reused = False
    if isinstance(index, str):
        index, reused = index_for_frame(volume, classify, index, index_options)
        if not reused:
            build_ms = index.build_ms
            build_jit_ms = index.compile_ms
    elif isinstance(index, SpatialIndex):
        if index_options:
            raise ParameterError(
                f"index options {sorted(index_options)} apply only when index is a name; "
                "this index is already built"
            )
        if mode != "dvr":
            # A prebuilt index serves an iso mode when it skips exactly what the spiked TF
            # does (the viewer keeps one per isovalue across camera and colour edits).
            if index.volume is not volume or not same_emptiness(index.tf, classify):
                raise ParameterError(
                    f"index: mode={mode!r} needs an index built for its isovalues: pass an index name "
                    f"(e.g. index={index.name!r}) or one built for classification_tf(tf, mode, iso)")
        elif index.volume is not volume or index.tf is not tf:
            raise ParameterError(
                f"index: this {index.name!r} index was built for another volume or transfer function; "
                "build a new one with build_index(volume, tf, name)"
            )
    else:
        raise ParameterError(f"index: expected an index name or a SpatialIndex, got {type(index).__name__}")

    if mode != "dvr" and not index.exact:
        raise ParameterError(f"index: {index.name!r} is approximate; mode={mode!r} needs an exact index "
                             "(e.g. index='auto')")
    if tf.sampling != "trilinear" and not index.exact:
        raise ParameterError(
            f"index: {index.name!r} is approximate and samples a resampled density; a "
            f"{type(tf).__name__} needs {tf.sampling} sampling of the voxels: use an exact index "
            "(e.g. index='auto')"
        )
    unit = tf.unit_distance if tf.unit_distance is not None else min_spacing
    origin = np.ascontiguousarray(volume.origin, dtype=np.float64)
    inv_spacing = np.ascontiguousarray(1.0 / volume.spacing, dtype=np.float64)
    cam = np.ascontiguousarray(camera.ray_params(width, height), dtype=np.float64)
    frame = Frame(
        cam=cam, width=width, height=height, x0=x0, y0=y0, origin=origin, inv_spacing=inv_spacing,
        dt=dt, ert=ert, shading=shading_array(shading), background=background_array(background),
        table=np.ascontiguousarray(tf.opacity_table(dt, unit), dtype=np.float32),
        v_lo=float(tf.value_range[0]), scale=float(tf.scale),
        clip_lo=clip_lo, clip_hi=clip_hi, open_lo=open_lo, open_hi=open_hi,
        any_open=bool(open_lo.any() or open_hi.any()), planes=_planes(volume, clip_planes),
        cap=cap, cut_lo=np.ascontiguousarray(clip_lo > 0.0),
        cut_hi=np.ascontiguousarray(clip_hi < np.array(volume.shape[::-1], np.float64) - 1.0),
        sampler=sampler_for(tf.sampling), mode=mode_marker,
    )
    record = index.traversal_record(_view(cam, origin, inv_spacing))
    jit_ms = build_jit_ms + _warm_up(record, data, frame, init)
    rgba = np.empty((h, w, 4), np.float32)
    samples = np.empty((h, w), np.int32)
    nonempty = np.empty((h, w), np.int32)
    t0 = time.perf_counter()
    run_tiles(tiles_kernel(record), w, h, record, data, frame, init, rgba, samples, nonempty)
    ms = (time.perf_counter() - t0) * 1e3
    n_samples = int(samples.sum(dtype=np.int64))
    stats: dict[str, Any] = {
        "ms": ms,
        "samples": n_samples,
        "samples_nonempty": int(nonempty.sum(dtype=np.int64)),
        "rays": w * h,
        "msamples_per_s": n_samples / ms / 1e3 if ms > 0 else float("nan"),
        "index": index.name,
        "build_ms": build_ms,
        "index_reused": reused,
        "jit_ms": jit_ms,
        "width": w,
        "height": h,
        "dt": dt,
        "ert": ert,
        "shading": bool(frame.shading[0]),
        "mode": mode,
    }
    if getattr(index, "auto", None) is not None:
        stats["auto"] = dict(index.auto)
    return Image(rgba, stats, samples)


def classification_tf(tf: TransferFunction, mode: str, iso) -> TransferFunction:
    """The TF an index is built for to render ``mode`` with isovalues ``iso``.

    ``tf`` itself for ``"dvr"``; for the iso modes a TF on ``tf``'s table grid that is
    non-empty around each isovalue (and, for ``"iso+dvr"``, wherever ``tf`` is), so
    bricks whose range holds an isovalue are kept. In ``"iso"`` mode it depends only on
    ``tf``'s value range and table size, not on its colours or opacity: an index built
    for it serves every TF edit that keeps the range.

    Parameters
    ----------
    tf : TransferFunction
    mode : {"dvr", "iso", "iso+dvr"}
    iso : float or sequence of float
        Isovalues in data units (ignored for ``"dvr"``).
    """
    one_of(mode, "mode", RENDER_MODES)
    if mode == "dvr":
        return tf
    return tf.with_spikes(np.atleast_1d(np.asarray(iso, np.float64)), keep_opacity=mode == "iso+dvr")


def iso_mode(mode: str, iso, iso_colors, tf: TransferFunction) -> Dvr | Iso | IsoDvr:
    """The driver's mode marker for ``mode``, ``iso`` and ``iso_colors`` (checked)."""
    one_of(mode, "mode", RENDER_MODES)
    if mode == "dvr":
        if iso is not None or iso_colors is not None:
            raise ParameterError("iso: isovalues apply only with mode='iso' or mode='iso+dvr'; got mode='dvr'")
        return Dvr()
    if iso is None:
        raise ParameterError(f"iso: mode={mode!r} needs isovalues, e.g. iso=0.5 or iso=[0.3, 0.7]")
    try:
        values = np.atleast_1d(np.asarray(iso, np.float64)).ravel()
    except (TypeError, ValueError):
        raise ParameterError(f"iso: expected a number or a list of numbers, got {iso!r}") from None
    if not 1 <= values.size <= MAX_ISOVALUES or not np.all(np.isfinite(values)):
        raise ParameterError(f"iso: expected 1 to {MAX_ISOVALUES} finite isovalues, got {iso!r}")
    if tf.sampling != "trilinear":
        raise ParameterError(f"mode: {mode!r} needs a field sampled trilinearly; a {type(tf).__name__} "
                             "samples label ids (render labels with mode='dvr')")
    if iso_colors is None:
        colors = np.ones((values.size, 4))
        colors[:, :3] = tf(values)[:, :3]
    else:
        try:
            rows = [list(map(float, c)) for c in iso_colors]
        except (TypeError, ValueError):
            raise ParameterError(f"iso_colors: expected one (r, g, b[, a]) per isovalue, got {iso_colors!r}") from None
        if len(rows) != values.size or any(len(r) not in (3, 4) for r in rows):
            raise ParameterError(f"iso_colors: expected {values.size} colour(s) (r, g, b[, a]) for "
                                 f"{values.size} isovalue(s), got {iso_colors!r}")
        colors = np.array([r + [1.0] if len(r) == 3 else r for r in rows], np.float64)
        if not (np.all(np.isfinite(colors)) and colors.min() >= 0.0 and colors.max() <= 1.0):
            raise ParameterError(f"iso_colors: expected numbers in [0, 1], got {iso_colors!r}")
    cls = Iso if mode == "iso" else IsoDvr
    return cls(np.ascontiguousarray(values), np.ascontiguousarray(colors))


def _view(cam: np.ndarray, origin: np.ndarray, inv_spacing: np.ndarray) -> View:
    """The camera as an index sees it (index space)."""
    return View(eye=(cam[0:3] - origin) * inv_spacing, direction=cam[3:6] * inv_spacing,
                perspective=bool(cam[12] != 0.0))


def _clip(volume: Volume, clip_box, clip_open):
    """Index-space clip box (intersected with the volume box) and its open faces."""
    nz, ny, nx = volume.shape
    lo = np.zeros(3)
    hi = np.array([nx - 1.0, ny - 1.0, nz - 1.0])
    open_lo = np.zeros(3, np.bool_)
    open_hi = np.zeros(3, np.bool_)
    checked = world_clip(clip_box, clip_open)
    if checked is None:
        return lo, hi, open_lo, open_hi
    box, flags = checked
    c_lo = (box[0] - volume.origin) / volume.spacing
    c_hi = (box[1] - volume.origin) / volume.spacing
    # A face of the clip box counts where it bounds the volume's box (or meets its face).
    open_lo = flags[0] & (c_lo >= lo)
    open_hi = flags[1] & (c_hi <= hi)
    return (np.ascontiguousarray(np.maximum(lo, c_lo)), np.ascontiguousarray(np.minimum(hi, c_hi)),
            np.ascontiguousarray(open_lo), np.ascontiguousarray(open_hi))


def _cap_shading(clip_cap, mode: str, shading) -> np.ndarray:
    """``clip_cap=`` as the frame's cap shading: zeros for no caps, else the render's
    shading parameters (the defaults where the volume is unshaded)."""
    if not isinstance(clip_cap, (bool, np.bool_)):
        raise ParameterError(f"clip_cap: expected True or False, got {clip_cap!r}")
    if not clip_cap:
        return np.zeros(SHADING_SIZE, np.float64)
    if mode != "dvr":
        raise ParameterError(f"clip_cap: caps shade the first DVR sample behind a cut face; got mode={mode!r}, "
                             "expected mode='dvr'")
    cap = shading_array(shading)
    return cap if cap[0] != 0.0 else shading_array(True)


def _planes(volume: Volume, clip_planes) -> np.ndarray:
    """World-space ``(point, normal)`` planes as index-space rows ``(nx, ny, nz, c)``, ``n . x >= c``.

    With ``world = origin + spacing * x``: ``n_w . (world - p) >= 0`` is
    ``(n_w * spacing) . x >= n_w . (p - origin)``.
    """
    if clip_planes is None:
        return np.zeros((0, 4), np.float64)
    try:
        planes = [np.array(p, dtype=np.float64) for p in clip_planes]
    except (TypeError, ValueError):
        planes = [np.zeros(0)]
    if len(planes) > MAX_CLIP_PLANES or any(p.shape != (2, 3) or not np.all(np.isfinite(p)) for p in planes):
        raise ParameterError(
            f"clip_planes: expected at most {MAX_CLIP_PLANES} planes ((px, py, pz), (nx, ny, nz)) of finite "
            f"numbers, got {clip_planes!r}"
        )
    rows = np.zeros((len(planes), 4), np.float64)
    for i, (point, normal) in enumerate(planes):
        if not np.any(normal):
            raise ParameterError(f"clip_planes[{i}]: expected a non-zero normal, got {tuple(normal)}")
        rows[i, :3] = normal * volume.spacing
        rows[i, 3] = float(normal @ (point - volume.origin))
    return rows


_WARM: set[tuple] = set()


def _warm_up(record, data, frame: Frame, init: np.ndarray) -> float:
    """Compile (or load from the on-disk cache) the driver for these argument types
    by rendering one pixel, so that ``stats["ms"]`` never includes JIT time.

    Returns the milliseconds spent, 0 when this combination was already warm.
    """
    # The driver specialises on the record, the voxel dtype, the initial-RGBA path and the
    # frame's sampler and mode markers (nearest labels, iso): each is its own compilation,
    # so an iso frame after a DVR one with the same index must warm up too.
    dtype = data.dtype.str if isinstance(data, np.ndarray) else (type(data), data.pool.dtype.str)
    key = (type(record), dtype, init.shape[0] > 0, type(frame.sampler), type(frame.mode))
    if key in _WARM:
        return 0.0
    t0 = time.perf_counter()
    tiny_init = init[:1, :1] if init.shape[0] else init
    tiles_kernel(record)(0, 1, record, data, frame, tiny_init, np.empty((1, 1, 4), np.float32),
                         np.empty((1, 1), np.int32), np.empty((1, 1), np.int32))
    _WARM.add(key)
    return (time.perf_counter() - t0) * 1e3
