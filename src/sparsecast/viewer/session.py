"""Per-client viewer state, the index cache and the frame renderer (no web code here).

A :class:`ViewerData` holds what every client shares: the volume it was started with,
its histogram and the initial TF. A :class:`Session` holds one client's state
(camera, TF, index) and renders frames; index builds are cached per session by
(TF, index, cell), so camera moves reuse the index and only a TF or index change
builds a new one.

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
from ..errors import SparsecastError
from ..index import available_indices, build_index
from ..index.auto import choose_index
from ..index.registry import AUTO
from ..render import render
from ..transfer import PRESETS, TransferFunction
from ..volume import Volume
from .messages import (
    CELL_SIZES,
    MAX_TF_POINTS,
    CameraSpec,
    IndexSpec,
    RenderRequest,
    TFSpec,
    frame_size,
)

__all__ = ["ViewerData", "Session", "tf_from_spec", "spec_from_tf", "spec_from_preset", "HISTOGRAM_BINS"]

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


def viewer_indices() -> list[str]:
    """Index names the viewer offers: ``auto`` (chosen per frame), then every index."""
    return [AUTO, *available_indices()]


@dataclass
class ViewerData:
    """What every client of one server shares."""

    volume: Volume
    tf: TFSpec
    index: IndexSpec = field(default_factory=lambda: IndexSpec(AUTO))
    camera: CameraSpec = field(default_factory=CameraSpec)
    dt: float | None = None
    #: the orbit frame (``Camera.orbit``'s ``up`` or ``view``): the client's azimuth and
    #: elevation turn about it
    up: str | None = None
    view: str | None = None

    def __post_init__(self) -> None:
        Camera.orbit(self.volume, up=self.up, view=self.view)  # a bad frame fails here, not per frame
        data = self.volume.data
        lo, hi = self.volume.value_range
        if not hi > lo:
            hi = lo + 1.0
        sample = data.ravel()[:: max(1, data.size // 4_000_000)]
        counts, _ = np.histogram(sample, bins=HISTOGRAM_BINS, range=(lo, hi))
        self.histogram = counts.astype(np.int64)
        self.histogram_range = (float(lo), float(hi))

    @classmethod
    def create(cls, volume: Volume, tf: TransferFunction | str | None = None,
               index: str | None = None, cell: int | None = None, **kw) -> "ViewerData":
        if tf is None:
            tf = "viridis"
        spec = spec_from_preset(tf, volume.value_range) if isinstance(tf, str) else spec_from_tf(tf)
        extra = {}
        if index is not None:
            if index not in viewer_indices():
                from ..errors import ParameterError

                raise ParameterError(f"index: unknown index {index!r}; expected one of: {', '.join(viewer_indices())}")
            if cell is not None and cell not in CELL_SIZES:
                from ..errors import ParameterError

                raise ParameterError(f"cell: expected one of {CELL_SIZES}, got {cell}")
            extra["index"] = IndexSpec(index, cell)
        return cls(volume, spec, **extra, **kw)

    def warm_up(self) -> float:
        """Compute the per-volume brick statistics and compile (or load) the kernels of
        the initial index with a tiny frame, so the first real frame is interactive.
        Returns the milliseconds spent."""
        t0 = time.perf_counter()
        s = Session(self)
        s.render_frame(Snapshot(self.camera, self.tf, self.index, 16, 16, True, "jpeg", 0))
        return (time.perf_counter() - t0) * 1e3

    def hello(self) -> dict[str, Any]:
        v = self.volume
        return {
            "type": "hello",
            "volume": {"name": v.name, "dims": list(v.dims), "dtype": str(v.dtype),
                       "value_range": list(self.histogram_range)},
            "histogram": {"counts": self.histogram.tolist(), "range": list(self.histogram_range)},
            "indices": viewer_indices(),
            "presets": list(PRESETS),
            # Colours of each preset at 32 evenly spaced positions (for the editor's strip).
            "colormaps": {p: colormap_samples(p) for p in PRESETS},
            "cells": list(CELL_SIZES),
            "limits": {"max_points": MAX_TF_POINTS, "preview": 256, "full": 512, "max_side": 1024, "min_side": 16},
            "state": {
                "camera": {"azimuth": self.camera.azimuth, "elevation": self.camera.elevation,
                           "zoom": self.camera.zoom, "pan": list(self.camera.pan)},
                "tf": {"points": [list(p) for p in self.tf.points], "colormap": self.tf.colormap,
                       "value_range": list(self.tf.value_range)},
                "index": {"name": self.index.name, "cell": self.index.cell},
            },
        }


@dataclass(frozen=True)
class Snapshot:
    """Immutable state a render works from (taken in the event loop, used in a thread)."""

    camera: CameraSpec
    tf: TFSpec
    index: IndexSpec
    width: int
    height: int
    preview: bool
    format: str
    seq: int


class Session:
    """One client's state and caches. ``update`` runs in the event loop; ``render_frame``
    and ``probe_naive`` run in a worker thread, one at a time."""

    def __init__(self, data: ViewerData) -> None:
        self.data = data
        self.camera = data.camera
        self.tf = data.tf
        self.index = data.index
        self.width: int | None = None
        self.height: int | None = None
        self._tfs: OrderedDict[TFSpec, TransferFunction] = OrderedDict()
        self._indices: OrderedDict[tuple, Any] = OrderedDict()
        self._naive_ms: OrderedDict[tuple, float] = OrderedDict()
        self.frames = 0
        # TF of the last full (not preview) frame: a preview with another TF means a
        # TF point is being dragged, and "auto" then picks a rebuild-cheap index.
        self._settled_tf: TFSpec | None = None

    def update(self, req: RenderRequest) -> Snapshot:
        if req.camera is not None:
            self.camera = req.camera
        if req.tf is not None:
            self.tf = req.tf
        if req.index is not None:
            self.index = req.index
        if req.width is not None:
            self.width = req.width
        if req.height is not None:
            self.height = req.height
        w, h = frame_size(self.width, self.height, req.preview)
        return Snapshot(self.camera, self.tf, self.index, w, h, req.preview, req.format, req.seq)

    # -- worker-thread side --------------------------------------------------
    def _tf(self, spec: TFSpec) -> TransferFunction:
        tf = self._tfs.get(spec)
        if tf is None:
            tf = tf_from_spec(spec)
            self._tfs[spec] = tf
            while len(self._tfs) > _INDEX_CACHE:
                self._tfs.popitem(last=False)
        else:
            self._tfs.move_to_end(spec)
        return tf

    def _index(self, tf_spec: TFSpec, tf: TransferFunction, ispec: IndexSpec):
        key = (tf_spec, ispec.name, ispec.cell)
        idx = self._indices.get(key)
        if idx is not None:
            self._indices.move_to_end(key)
            return idx, 0.0, False
        opts = {} if ispec.cell is None else {"cell": ispec.cell}
        t0 = time.perf_counter()
        idx = build_index(self.data.volume, tf, ispec.name, **opts)
        ms = (time.perf_counter() - t0) * 1e3
        self._indices[key] = idx
        while len(self._indices) > _INDEX_CACHE:
            self._indices.popitem(last=False)
        return idx, ms, True

    def _camera(self, c: CameraSpec) -> Camera:
        return Camera.orbit(self.data.volume, c.azimuth, c.elevation, zoom=c.zoom, pan=c.pan,
                            up=self.data.up, view=self.data.view)

    @staticmethod
    def _view_key(s: Snapshot, w: int | None = None, h: int | None = None) -> tuple:
        return (s.tf, s.camera, s.width if w is None else w, s.height if h is None else h)

    def render_frame(self, s: Snapshot) -> tuple[bytes, dict[str, Any]]:
        """Render ``s``; return the encoded image and the status message."""
        t_all = time.perf_counter()
        tf = self._tf(s.tf)
        ispec, auto = s.index, None
        if ispec.name == AUTO:
            editing = s.preview and s.tf != self._settled_tf
            name, auto = choose_index(self.data.volume, tf, editing=editing, names=available_indices())
            ispec = IndexSpec(name, None)
        if not s.preview:
            self._settled_tf = s.tf
        idx, build_ms, rebuilt = self._index(s.tf, tf, ispec)
        img = render(self.data.volume, tf, self._camera(s.camera), s.width, s.height,
                     dt=self.data.dt, index=idx, background="black")
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
            "rebuilt": rebuilt,
            "rebuild_ms": round(build_ms, 3),
            "frame_ms": round(st["ms"], 3),
            "jit_ms": round(st.get("jit_ms", 0.0), 3),
            "encode_ms": round(enc_ms, 3),
            "total_ms": round((time.perf_counter() - t_all) * 1e3, 3),
            "samples": int(st["samples"]),
            "samples_nonempty": int(st["samples_nonempty"]),
            "naive_ms": None if naive_ms is None else round(naive_ms, 3),
            "speedup": None if naive_ms is None or st["ms"] <= 0 else round(naive_ms / st["ms"], 2),
            "speedup_source": None if naive_ms is None else ("measured" if ispec.name == "naive" else "estimated"),
        }
        self.last_frame_ms = st["ms"]
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
        tf = self._tf(s.tf)
        img = render(self.data.volume, tf, self._camera(s.camera), pw, ph, dt=self.data.dt,
                     index="naive", background="black")
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
