"""Per-client viewer state, the index cache and the frame renderer (no web code here).

A :class:`ViewerData` holds what every client shares: the volume (or time series) it
was started with, its histogram, the initial TF and, for a label volume, its label
table (ids, colours, voxel counts). A :class:`Session` holds one client's state
(camera, TF or label visibility, index, mode and isovalues, clip, time step) and
renders frames. Index builds are cached per session by what decides emptiness: (time
step, classification, index, cell), where the classification is the TF (DVR), the
label table (labels), the TF's value range and the isovalues (``iso``: colour and
opacity edits reuse the index) or TF and isovalues (``iso+dvr``). Camera moves and
clip changes never rebuild; the clip is a render parameter every index honours.

Speedup over naive: ``naive_ms / frame_ms`` where ``naive_ms`` is the last naive
time known for this view (same TF, camera and image size): the frame itself when the
index is ``naive``; otherwise an estimate from a naive render of the same view (TF,
camera) at half the width and height (:data:`NAIVE_PROBE_SCALE`), its time scaled by
the pixel-count ratio. The probe runs once per view, only when the client has been
idle for a while after a full frame (``server.IDLE_PROBE_S``), so it does not sit in
front of interactive frames; until then ``speedup`` is ``null``. Low-resolution rays
are less cache-coherent, so the estimate tends to overstate the naive time (by about
10-25 % on the 256^3 demo at 512^2) and with it the speedup; choosing ``naive`` in the
viewer gives a measured figure.
"""

from __future__ import annotations

import io
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..camera import Camera
from ..errors import ParameterError, SparsecastError
from ..index import available_indices, build_index
from ..index.auto import choose_index
from ..index.registry import AUTO
from ..render import classification_tf, render
from ..series import VolumeSeries
from ..transfer import PRESETS, LabelTransferFunction, TransferFunction
from ..volume import Volume
from .messages import (
    CELL_SIZES,
    FULL_CLIP,
    MAX_CLIP_PLANES,
    MAX_ISOVALUES,
    MAX_TF_POINTS,
    MODES,
    CameraSpec,
    ClipSpec,
    IndexSpec,
    LabelSpec,
    RenderRequest,
    TFSpec,
    frame_size,
)

__all__ = ["ViewerData", "Session", "LabelTable", "tf_from_spec", "spec_from_tf", "spec_from_preset",
           "clip_world", "frame_camera", "HISTOGRAM_BINS"]

#: one visible label: ``(id, r, g, b, a)``; a tuple of them is a label TF's cache key
LabelEntry = tuple[int, float, float, float, float]

HISTOGRAM_BINS = 128
NAIVE_PROBE_SCALE = 0.5
_INDEX_CACHE = 4
#: views whose naive time a session remembers (for the speed-up readout), least recent dropped
NAIVE_CACHE = 256
_JPEG_QUALITY = 88


def spec_from_preset(name: str, value_range: tuple[float, float], threshold: float = 0.1) -> TFSpec:
    """Editable TF for a preset: its colour map plus a few opacity control points."""
    tf = TransferFunction.preset(name, (0.0, 1.0), threshold=threshold)
    pts = tf.points
    if len(pts) > 8:
        # Colour-map presets: a ramp; keep its corners (transparent head, top).
        keep = [0, 1, len(pts) - 1] if pts[0, 4] == 0 and pts[1, 0] > pts[0, 0] else [0, len(pts) - 1]
        pts = pts[keep]
    lo, hi = (float(v) for v in value_range)
    if not hi > lo:
        hi = lo + 1.0
    return TFSpec(tuple(tuple(float(v) for v in p) for p in pts), name.lower(), (lo, hi))


def spec_from_tf(tf: TransferFunction) -> TFSpec:
    """Editable spec of any TF (resampled to at most MAX_TF_POINTS points, no colour map)."""
    lo, hi = tf.value_range
    pts = np.array(tf.points, dtype=np.float64)
    if len(pts) > MAX_TF_POINTS:
        xs = np.linspace(lo, hi, MAX_TF_POINTS)
        pts = np.column_stack([xs, tf(xs)])
    x = np.clip((pts[:, 0] - lo) / (hi - lo), 0.0, 1.0)
    out = np.column_stack([x, np.clip(pts[:, 1:], 0.0, 1.0)])
    return TFSpec(tuple(tuple(float(v) for v in p) for p in out), None, (float(lo), float(hi)))


def tf_from_spec(spec: TFSpec) -> TransferFunction:
    """Build the TF: opacity from the control points; colour from the colour map when
    one is named (sampled at its own stops and at the points), else from the points."""
    op = np.array(spec.points, dtype=np.float64).reshape(-1, 5)
    if spec.colormap is not None:
        # Colour stops of the preset (hand-made presets ignore the threshold).
        cm = TransferFunction.preset(spec.colormap, (0.0, 1.0), threshold=0.0).points

        def rgb_at(x):
            return np.column_stack([np.interp(x, cm[:, 0], cm[:, c]) for c in (1, 2, 3)])

        op[:, 1:4] = rgb_at(op[:, 0])
        extra_x = np.setdiff1d(cm[:, 0], op[:, 0])
        extra_a = np.interp(extra_x, op[:, 0], op[:, 4]) if len(op) else np.zeros_like(extra_x)
        extra = np.column_stack([extra_x, rgb_at(extra_x), extra_a])
        allp = np.vstack([op, extra])
        op = allp[np.argsort(allp[:, 0], kind="stable")]
    lo, hi = spec.value_range
    pts = op.copy()
    pts[:, 0] = lo + op[:, 0] * (hi - lo)
    # Rounding in the mapping must not unsort ties.
    pts[:, 0] = np.maximum.accumulate(pts[:, 0])
    return TransferFunction(pts, (lo, hi), name=spec.colormap or "custom")


@dataclass(frozen=True)
class LabelTable:
    """The label table of a label volume: every id it holds, a colour for each (the
    TF's where it has one, distinct colours for the others), voxel counts, the ids the
    starting TF shows, and that TF (for its unit distance and name)."""

    ids: tuple[int, ...]
    counts: tuple[int, ...]
    colors: dict[int, tuple[float, float, float, float]]
    visible: tuple[int, ...]
    tf: LabelTransferFunction

    @classmethod
    def create(cls, volume: Volume, tf: LabelTransferFunction) -> "LabelTable":
        found = volume.label_counts()
        if found is None:
            lo, hi = volume.value_range
            raise ParameterError(
                f"tf: a label TF needs a label volume (integer ids, at most 4096 distinct values); "
                f"{volume.name} has values in [{lo:g}, {hi:g}]")
        ids = tuple(int(i) for i in found[0])
        # Ids the TF leaves out (or hides with opacity 0) get colours of their own, so that
        # ticking one shows it: the palette entries after the ones a TF of generated
        # colours (labels([ids])) took, so they differ from those.
        own = {i: tuple(float(x) for x in c) for i, c in tf.labels.items() if i in set(ids) and c[3] > 0}
        palette = list(TransferFunction.labels(list(range(len(ids) + len(own)))).labels.values())
        missing = [i for i in ids if i not in own]
        colors = {i: tuple(float(x) for x in palette[len(own) + k]) for k, i in enumerate(missing)}
        colors.update(own)
        visible = tuple(i for i in tf.visible if i in colors)
        return cls(ids, tuple(int(c) for c in found[1]), colors, visible, tf)  # type: ignore[arg-type]

    def entries(self, visible: tuple[int, ...], colors: dict[int, tuple]) -> tuple[LabelEntry, ...]:
        return tuple((i, *colors[i]) for i in visible)  # type: ignore[misc]

    def tf_for(self, entries: tuple[LabelEntry, ...]) -> LabelTransferFunction:
        """The label TF showing ``entries`` (every other id hidden), as
        ``tf.hidden(...)`` / ``tf.with_labels(...)`` build it."""
        shown = {e[0]: e[1:] for e in entries} or {self.ids[0]: (0.0, 0.0, 0.0, 0.0)}
        return LabelTransferFunction(shown, cmap=self.tf.cmap, unit_distance=self.tf.unit_distance,
                                     name=self.tf.name)


def clip_world(volume: Volume, clip: ClipSpec) -> dict[str, Any]:
    """``render`` keyword arguments (world units) for ``clip`` (fractions of the volume
    box); nothing for a clip of the whole box, which is what ``render`` does by default."""
    if clip.is_full:
        return {}
    lo, hi = volume.bounds
    ext = hi - lo
    box = (tuple(lo + np.asarray(clip.box[0]) * ext), tuple(lo + np.asarray(clip.box[1]) * ext))
    planes = [(tuple(lo + np.asarray(p[:3]) * ext), tuple(p[3:])) for p in clip.planes]
    return {"clip_box": box, "clip_planes": planes or None}


def frame_camera(camera: Camera, width: int, height: int) -> dict[str, Any]:
    """The camera a frame was rendered with, as the page projects world points with it
    (its clip-box overlay): :meth:`Camera.ray_params` by name.

    The ray of normalised screen point ``(u, v)`` in ``[-1, 1]`` (``v`` up) is
    ``eye + u right + v up`` along ``forward`` (orthographic) or from ``eye`` along
    ``forward + u right + v up`` (perspective); ``right`` and ``up`` are the image
    plane's half extents (they carry the field of view and the aspect ``width / height``),
    so the page needs no copy of the orbit and projection maths.
    """
    p = camera.ray_params(width, height)
    return {"eye": p[0:3].tolist(), "forward": p[3:6].tolist(), "right": p[6:9].tolist(),
            "up": p[9:12].tolist(), "perspective": bool(p[12])}


def viewer_indices() -> list[str]:
    """Index names the viewer offers: ``auto`` (chosen per frame), then every index."""
    return [AUTO, *available_indices()]


@dataclass
class ViewerData:
    """What every client of one server shares.

    ``volume`` is the volume shown, or step ``time`` of ``series`` (then the TF and
    the histogram's range span every step; the histogram counts that step's voxels).
    ``tf`` is ``None`` for a label volume, whose colours are ``labels``.
    """

    volume: Volume
    tf: TFSpec | None
    index: IndexSpec = field(default_factory=lambda: IndexSpec(AUTO))
    camera: CameraSpec = field(default_factory=CameraSpec)
    dt: float | None = None
    #: the orbit frame (``Camera.orbit``'s ``up`` or ``view``): the client's azimuth and
    #: elevation turn about it
    up: str | None = None
    view: str | None = None
    series: VolumeSeries | None = None
    time: int = 0
    labels: LabelTable | None = None
    mode: str = "dvr"
    #: isovalues (data units); default: the middle of the value range
    iso: tuple[float, ...] | None = None
    clip: ClipSpec = FULL_CLIP
    #: a ``dask.distributed.Client``: DVR frames render on its cluster (``view
    #: --scheduler``); the iso modes and the naive-time probe stay in this process
    client: Any = None
    #: pieces to cut the volume into on the cluster (default one per worker thread)
    pieces: int | None = None

    def __post_init__(self) -> None:
        Camera.orbit(self.volume, up=self.up, view=self.view)  # a bad frame fails here, not per frame
        if self.mode not in MODES:
            raise ParameterError(f"mode: expected one of {', '.join(MODES)}, got {self.mode!r}")
        if self.mode != "dvr" and self.labels is not None:
            raise ParameterError(f"mode: {self.mode!r} needs a scalar field; a label volume renders with 'dvr'")
        if self.series is not None:
            self.time = self.series.step(self.time)
        if (self.tf is None) == (self.labels is None):
            raise ParameterError("tf: expected a TF spec for a scalar volume or a label table, not both")
        lo, hi = self.series.value_range if self.series is not None else self.volume.value_range
        if not hi > lo:
            hi = lo + 1.0
        if self.series is None:
            counts, _ = self.volume.histogram(HISTOGRAM_BINS)
        else:  # the series' range: bin the first step's voxels over it
            data = self.volume.data
            sample = data.ravel()[:: max(1, data.size // 4_000_000)]
            counts, _ = np.histogram(sample, bins=HISTOGRAM_BINS, range=(lo, hi))
        self.histogram = counts.astype(np.int64)
        self.histogram_range = (float(lo), float(hi))
        if self.iso is None:
            self.iso = (0.5 * (self.histogram_range[0] + self.histogram_range[1]),)
        if not 1 <= len(self.iso) <= MAX_ISOVALUES or not all(np.isfinite(self.iso)):
            raise ParameterError(f"iso: expected 1 to {MAX_ISOVALUES} finite isovalues, got {self.iso!r}")

    @classmethod
    def create(cls, volume: Volume | VolumeSeries, tf: TransferFunction | str | None = None,
               index: str | None = None, cell: int | None = None, *, time: int = 0, **kw) -> "ViewerData":
        """Viewer data for a volume or a time series (shown at step ``time``).

        ``tf``: a preset name (over the value range of the volume, or of every step
        of a series), a :class:`TransferFunction`, or a :class:`LabelTransferFunction`
        (then the volume is shown as a label volume with its table of ids).
        """
        series = None
        if isinstance(volume, VolumeSeries):
            series, volume = volume, volume[volume.step(time)]
            kw["series"], kw["time"] = series, time
        elif time != 0:
            raise ParameterError(f"time: {volume.name} is one volume, not a time series; got time={time!r}")
        value_range = series.value_range if series is not None else volume.value_range
        if tf is None:
            tf = "viridis"
        labels = None
        if isinstance(tf, LabelTransferFunction):
            labels, spec = LabelTable.create(volume, tf), None
        elif isinstance(tf, str):
            spec = spec_from_preset(tf, value_range)
        else:
            spec = spec_from_tf(tf)
        extra: dict[str, Any] = {"labels": labels}
        if index is not None:
            if index not in viewer_indices():
                raise ParameterError(f"index: unknown index {index!r}; expected one of: {', '.join(viewer_indices())}")
            if cell is not None and cell not in CELL_SIZES:
                raise ParameterError(f"cell: expected one of {CELL_SIZES}, got {cell}")
            extra["index"] = IndexSpec(index, cell)
        return cls(volume, spec, **extra, **kw)

    def volume_at(self, t: int) -> Volume:
        """The volume of time step ``t`` (the one volume when this is not a series)."""
        return self.volume if self.series is None else self.series[t]

    def warm_up(self) -> float:
        """Compute the per-volume brick statistics and compile (or load) the kernels of
        the initial index with a tiny frame, so the first real frame is interactive.
        Returns the milliseconds spent."""
        t0 = time.perf_counter()
        s = Session(self)
        s.render_frame(s.update(RenderRequest(preview=True, width=16, height=16)))
        return (time.perf_counter() - t0) * 1e3

    def hello(self) -> dict[str, Any]:
        v = self.volume
        lt = self.labels
        return {
            "type": "hello",
            "volume": {"name": v.name if self.series is None else self.series.name, "dims": list(v.dims),
                       "dtype": str(v.dtype), "value_range": list(self.histogram_range),
                       # World box [[x0, y0, z0], [x1, y1, z1]] that clip fractions refer to
                       # (clip_world); every step of a series shares it.
                       "bounds": [[float(c) for c in corner] for corner in v.bounds]},
            # A label volume: the page's label table (ids ascending, parallel lists).
            "labels": None if lt is None else {
                "ids": list(lt.ids), "counts": list(lt.counts),
                "colors": [list(lt.colors[i]) for i in lt.ids], "visible": list(lt.visible),
                "smooth": bool(lt.tf.smooth)},
            # A time series: the page's time slider.
            "series": None if self.series is None else {"steps": len(self.series), "names": list(self.series.names)},
            "modes": list(MODES) if lt is None else ["dvr"],
            "histogram": {"counts": self.histogram.tolist(), "range": list(self.histogram_range)},
            "indices": viewer_indices(),
            "presets": list(PRESETS),
            # Colours of each preset at 32 evenly spaced positions (for the editor's strip).
            "colormaps": {p: colormap_samples(p) for p in PRESETS},
            "cells": list(CELL_SIZES),
            "limits": {"max_points": MAX_TF_POINTS, "preview": 256, "full": 512, "max_side": 1024, "min_side": 16,
                       "max_iso": MAX_ISOVALUES, "max_clip_planes": MAX_CLIP_PLANES},
            "state": {
                "camera": {"azimuth": self.camera.azimuth, "elevation": self.camera.elevation,
                           "zoom": self.camera.zoom, "pan": list(self.camera.pan)},
                "tf": None if self.tf is None else {
                    "points": [list(p) for p in self.tf.points], "colormap": self.tf.colormap,
                    "value_range": list(self.tf.value_range)},
                "index": {"name": self.index.name, "cell": self.index.cell},
                "mode": self.mode,
                "iso": list(self.iso or ()),
                "clip": {"box": [list(self.clip.box[0]), list(self.clip.box[1])],
                         "planes": [list(p) for p in self.clip.planes], "cap": self.clip.cap},
                "time": self.time,
            },
        }


@dataclass(frozen=True)
class Snapshot:
    """Immutable state a render works from (taken in the event loop, used in a thread).

    ``tf`` is ``None`` for a label volume, whose TF is ``labels`` (the visible ids
    with their colours)."""

    camera: CameraSpec
    tf: TFSpec | None
    index: IndexSpec
    width: int
    height: int
    preview: bool
    format: str
    seq: int
    mode: str = "dvr"
    iso: tuple[float, ...] = ()
    clip: ClipSpec = FULL_CLIP
    labels: tuple[LabelEntry, ...] | None = None
    time: int = 0
    #: label volumes: smooth boundaries (interpolated per-label masks) instead of nearest voxels
    smooth: bool = False

    @property
    def tf_key(self) -> tuple:
        """What the colours come from: the TF spec, or the visible labels (and smoothing)."""
        return ("labels", self.labels, self.smooth) if self.tf is None else ("tf", self.tf)

    @property
    def classification(self) -> tuple:
        """What decides emptiness, so what an index is built for (a cache key)."""
        if self.mode == "dvr":
            return self.tf_key
        if self.mode == "iso":  # the spiked TF keeps only the range's table grid of the TF
            return ("iso", self.tf.value_range, self.iso)  # type: ignore[union-attr]
        return ("iso+dvr", self.tf, self.iso)


class Session:
    """One client's state and caches. ``update`` runs in the event loop; ``render_frame``
    and ``probe_naive`` run in a worker thread, one at a time."""

    def __init__(self, data: ViewerData) -> None:
        self.data = data
        self.camera = data.camera
        self.tf = data.tf
        self.index = data.index
        self.mode = data.mode
        self.iso: tuple[float, ...] = tuple(data.iso or ())
        self.clip = data.clip
        self.time = data.time
        lt = data.labels
        self.label_visible: tuple[int, ...] = () if lt is None else lt.visible
        self.label_colors: dict[int, tuple] = {} if lt is None else dict(lt.colors)
        self.label_smooth = False if lt is None else bool(lt.tf.smooth)
        self.width: int | None = None
        self.height: int | None = None
        self._tfs: OrderedDict[tuple, TransferFunction] = OrderedDict()
        self._indices: OrderedDict[tuple, Any] = OrderedDict()
        self._naive_ms: OrderedDict[tuple, float] = OrderedDict()
        self.frames = 0
        # Classification of the last full (not preview) frame: a preview with another
        # one means a TF point or the isovalue is being dragged, and "auto" then picks a
        # rebuild-cheap index.
        self._settled: tuple | None = None

    def update(self, req: RenderRequest) -> Snapshot:
        # A message carries only what changed: every field it sets replaces the state's.
        for name in ("camera", "tf", "index", "width", "height", "mode", "iso", "clip", "time"):
            value = getattr(req, name)
            if value is not None:
                setattr(self, name, value)
        if req.labels is not None:
            self._apply_labels(req.labels)
        w, h = frame_size(self.width, self.height, req.preview)
        lt = self.data.labels
        labels = None if lt is None else lt.entries(self.label_visible, self.label_colors)
        return Snapshot(self.camera, self.tf, self.index, w, h, req.preview, req.format, req.seq,
                        self.mode, self.iso, self.clip, labels, self.time, lt is not None and self.label_smooth)

    def _apply_labels(self, spec: LabelSpec) -> None:
        for i, *rgba in spec.colors:
            self.label_colors[i] = tuple(rgba)
        if spec.visible is not None:
            self.label_visible = spec.visible
        if spec.smooth is not None:
            self.label_smooth = spec.smooth

    # -- worker-thread side --------------------------------------------------
    def _tf(self, s: Snapshot) -> TransferFunction:
        key = s.tf_key
        tf = self._tfs.get(key)
        if tf is None:
            tf = tf_from_spec(s.tf) if s.tf is not None else self.data.labels.tf_for(s.labels)  # type: ignore[union-attr]
            if s.tf is None:
                tf = tf.smoothed(s.smooth)
            self._tfs[key] = tf
            while len(self._tfs) > _INDEX_CACHE:
                self._tfs.popitem(last=False)
        else:
            self._tfs.move_to_end(key)
        return tf

    def _index(self, s: Snapshot, volume: Volume, classify: TransferFunction, ispec: IndexSpec):
        key = (s.time, s.classification, ispec.name, ispec.cell)
        idx = self._indices.get(key)
        if idx is not None:
            self._indices.move_to_end(key)
            return idx, 0.0, False
        opts = {} if ispec.cell is None else {"cell": ispec.cell}
        t0 = time.perf_counter()
        idx = build_index(volume, classify, ispec.name, **opts)
        ms = (time.perf_counter() - t0) * 1e3
        self._indices[key] = idx
        while len(self._indices) > _INDEX_CACHE:
            self._indices.popitem(last=False)
        return idx, ms, True

    def _camera(self, c: CameraSpec, volume: Volume | None = None) -> Camera:
        # Every step of a series shares one grid, so any step frames the same camera.
        return Camera.orbit(volume or self.data.volume, c.azimuth, c.elevation, zoom=c.zoom, pan=c.pan,
                            up=self.data.up, view=self.data.view)

    @staticmethod
    def _view_key(s: Snapshot, w: int | None = None, h: int | None = None) -> tuple:
        return (s.tf_key, s.camera, s.mode, s.iso, s.clip, s.time,
                s.width if w is None else w, s.height if h is None else h)

    def _render_kw(self, s: Snapshot, volume: Volume) -> dict[str, Any]:
        """What ``render`` takes besides the index for snapshot ``s``: clip (world
        units), mode and isovalues, step, background."""
        kw: dict[str, Any] = dict(dt=self.data.dt, background="black", **clip_world(volume, s.clip))
        if s.mode != "dvr":
            kw.update(mode=s.mode, iso=list(s.iso))
        elif s.clip.cap and not s.clip.is_full:
            kw.update(clip_cap=True)  # caps are a DVR feature; the iso modes have surfaces already
        return kw

    def render_frame(self, s: Snapshot) -> tuple[bytes, dict[str, Any]]:
        """Render ``s``; return the encoded image and the status message."""
        t_all = time.perf_counter()
        volume = self.data.volume_at(s.time)
        tf = self._tf(s)
        classify = classification_tf(tf, s.mode, s.iso)
        ispec, auto = s.index, None
        if ispec.name == AUTO:
            editing = s.preview and s.classification != self._settled
            name, auto = choose_index(volume, classify, editing=editing, names=available_indices())
            ispec = IndexSpec(name, None)
        if not s.preview:
            self._settled = s.classification
        camera = self._camera(s.camera, volume)
        if self.data.client is not None and s.mode == "dvr" and not self._render_kw(s, volume).get("clip_cap"):
            # The pieces on the cluster keep and rebuild their own indices.
            img = render(volume, tf, camera, s.width, s.height, index=ispec.name,
                         client=self.data.client, pieces=self.data.pieces, **self._render_kw(s, volume))
            idx, build_ms = None, float(img.stats["build_ms"])
            rebuilt = build_ms > 0
        else:
            idx, build_ms, rebuilt = self._index(s, volume, classify, ispec)
            # DVR: the TF the cached index was built for (equal to tf; render checks identity).
            img = render(volume, idx.tf if s.mode == "dvr" else tf, camera, s.width,
                         s.height, index=idx, **self._render_kw(s, volume))
        st = img.stats
        if ispec.name == "naive":
            self._remember_naive(self._view_key(s), st["ms"])
        t_enc = time.perf_counter()
        payload = encode(img.rgba, s.format)
        enc_ms = (time.perf_counter() - t_enc) * 1e3
        naive_ms = self._naive_ms.get(self._view_key(s))
        self.frames += 1
        status = {
            "type": "frame",
            "seq": s.seq,
            "width": s.width,
            "height": s.height,
            "preview": s.preview,
            "format": s.format,
            "bytes": len(payload),
            "index": ispec.name,
            "auto": auto,
            "cell": getattr(idx, "cell", None),
            "mode": s.mode,
            "time": s.time,
            "rebuilt": rebuilt,
            "rebuild_ms": round(build_ms, 3),
            "frame_ms": round(st["ms"], 3),
            "jit_ms": round(st.get("jit_ms", 0.0), 3),
            "encode_ms": round(enc_ms, 3),
            "total_ms": round((time.perf_counter() - t_all) * 1e3, 3),
            "samples": int(st["samples"]),
            "samples_nonempty": int(st["samples_nonempty"]),
            "pieces": st.get("pieces"),
            "naive_ms": None if naive_ms is None else round(naive_ms, 3),
            "speedup": None if naive_ms is None or st["ms"] <= 0 else round(naive_ms / st["ms"], 2),
            "speedup_source": None if naive_ms is None else ("measured" if ispec.name == "naive" else "estimated"),
            "camera": frame_camera(camera, s.width, s.height),
        }
        self.last_frame_ms = st["ms"]
        self.last_rgba = img.rgba  # (H, W, 4) premultiplied float32: what was encoded (tests)
        return payload, status

    def _remember_naive(self, key: tuple, ms: float) -> None:
        """Keep a view's naive time, at most :data:`NAIVE_CACHE` of them (every TF edit
        is a new view: unbounded, this grew by megabytes over a long session)."""
        self._naive_ms[key] = ms
        self._naive_ms.move_to_end(key)
        while len(self._naive_ms) > NAIVE_CACHE:
            self._naive_ms.popitem(last=False)

    def close(self) -> None:
        """Drop every cache (the client has gone): indices, TFs, naive times."""
        self._indices.clear()
        self._tfs.clear()
        self._naive_ms.clear()

    def needs_probe(self, s: Snapshot) -> bool:
        return not s.preview and s.index.name != "naive" and self._view_key(s) not in self._naive_ms

    def probe_naive(self, s: Snapshot, frame_ms: float) -> dict[str, Any]:
        """Estimate the naive time of view ``s`` from a small naive render; a status update."""
        pw = max(16, int(round(s.width * NAIVE_PROBE_SCALE)))
        ph = max(16, int(round(s.height * NAIVE_PROBE_SCALE)))
        volume = self.data.volume_at(s.time)
        img = render(volume, self._tf(s), self._camera(s.camera, volume), pw, ph, index="naive",
                     **self._render_kw(s, volume))
        est = img.stats["ms"] * (s.width * s.height) / (pw * ph)
        self._remember_naive(self._view_key(s), est)
        return {
            "type": "speedup",
            "seq": s.seq,
            "naive_ms": round(est, 3),
            "speedup": round(est / frame_ms, 2) if frame_ms > 0 else None,
            "speedup_source": "estimated",
            "probe": [pw, ph],
        }


def colormap_samples(name: str, n: int = 32) -> list[list[float]]:
    """Straight RGB of preset ``name`` at ``n`` positions in [0, 1] (as :func:`tf_from_spec` uses it)."""
    cm = TransferFunction.preset(name, (0.0, 1.0), threshold=0.0).points
    xs = np.linspace(0.0, 1.0, n)
    rgb = np.column_stack([np.interp(xs, cm[:, 0], cm[:, c]) for c in (1, 2, 3)])
    return np.round(rgb, 4).tolist()


def encode(rgba: np.ndarray, fmt: str) -> bytes:
    """Premultiplied RGBA composited over black (opaque) -> JPEG or PNG bytes."""
    from PIL import Image as PILImage

    rgb = np.clip(rgba[..., :3] * 255.0 + 0.5, 0, 255).astype(np.uint8)
    buf = io.BytesIO()
    pil = PILImage.fromarray(rgb, "RGB")
    if fmt == "png":
        pil.save(buf, format="PNG", compress_level=1)
    else:
        pil.save(buf, format="JPEG", quality=_JPEG_QUALITY)
    return buf.getvalue()


__all__ += ["Snapshot", "encode", "SparsecastError"]
