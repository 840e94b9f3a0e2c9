"""Validation of the JSON messages a viewer client sends over the WebSocket.

Every message is checked here before the server acts on it: JSON object of at most
:data:`MAX_MESSAGE_BYTES`, known keys only, numbers finite and in range, names from
fixed lists (TF presets, registered indices), image sizes capped. A bad message
raises :class:`MessageError` (a :class:`~sparsecast.errors.ParameterError`); the
server replies ``{"type": "error", "message": ...}`` and keeps the connection.

Client -> server (one message type; every section optional)::

    {"type": "render",
     "seq": 12,                                   # echoed in the frame status
     "camera": {"azimuth": 30, "elevation": 20, "zoom": 1.0},
     "tf": {"points": [[x, r, g, b, a], ...],     # x normalised to [0, 1] of value_range
            "colormap": "viridis" | null,         # a TF preset; null: colours from points
            "value_range": [lo, hi]},
     "index": {"name": "grid-pc", "cell": 8 | null},
     "width": 512, "height": 512,                 # canvas size, each 16..1024
     "preview": false,                            # true: capped to 256 x 256 (dragging)
     "format": "jpeg" | "png",
     "mode": "dvr" | "iso" | "iso+dvr",
     "iso": [v, ...],                             # 1..8 isovalues in data units (a number is one)
     "clip": {"box": [[x0, y0, z0], [x1, y1, z1]],    # fractions [0, 1] of the volume box, lo <= hi
              "planes": [[px, py, pz, nx, ny, nz], ...]},  # point: fractions; normal: world axes
     "labels": {"visible": [id, ...],             # label volumes: the ids shown (others hidden)
                "colors": [[id, r, g, b, a], ...]},  # per-id colour overrides, in [0, 1]
     "time": 3}                                   # time series: the step shown

The sections update the session's state; a render of the new state is requested.
Isovalues are in data units (what ``render(iso=...)`` takes, so a value means the same
whatever TF range the client edits). ``clip`` replaces the whole clip state (``{}``: no
clipping); ``labels`` replaces the visible set when ``visible`` is given and recolours
the ids in ``colors``. ``labels`` and ``time`` are accepted only when the viewer shows a
label volume or a series (``label_ids`` / ``steps`` of :func:`parse_message`); a label
volume renders ``dvr`` only.

Server -> client (built in :mod:`.session`, nothing to validate here): the ``hello``
(volume, with its world ``bounds`` that clip fractions refer to; lists; the starting
state) and, before each frame's image, its status, whose ``camera`` is the camera that
frame was rendered with (:func:`~sparsecast.viewer.session.frame_camera`): the page
projects the clip box, its clip planes and their drag handles with it. The page keeps
its plane rows (a disabled one included) and sends the enabled ones as ``clip.planes``
(``clipMessage`` in ``static/interaction.js``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Iterable

from ..errors import ParameterError

__all__ = [
    "MessageError",
    "CameraSpec",
    "TFSpec",
    "IndexSpec",
    "ClipSpec",
    "LabelSpec",
    "RenderRequest",
    "parse_message",
    "MAX_MESSAGE_BYTES",
    "MAX_TF_POINTS",
    "MIN_SIDE",
    "MAX_SIDE",
    "PREVIEW_SIDE",
    "FULL_SIDE",
    "CELL_SIZES",
    "MODES",
    "MAX_ISOVALUES",
    "MAX_CLIP_PLANES",
    "FULL_CLIP",
]

#: Largest accepted message (UTF-8 bytes).
MAX_MESSAGE_BYTES = 64 * 1024
#: Most TF control points per message.
MAX_TF_POINTS = 64
#: Image side limits (pixels).
MIN_SIDE, MAX_SIDE = 16, 1024
#: Preview frames (while dragging) fit in PREVIEW_SIDE x PREVIEW_SIDE.
PREVIEW_SIDE = 256
#: Full frames when the client does not say its canvas size.
FULL_SIDE = 512
#: Grid cell sizes (voxels per edge).
CELL_SIZES = (4, 8, 16, 32, 64)
#: Camera limits.
MAX_ABS_AZIMUTH = 1e6
ZOOM_RANGE = (0.05, 50.0)
#: Value ranges: finite and below this magnitude.
MAX_ABS_VALUE = 1e300
_MAX_NAME = 64
#: Render modes (``render(mode=...)``), isovalues and clip planes per message.
MODES = ("dvr", "iso", "iso+dvr")
MAX_ISOVALUES = 8
MAX_CLIP_PLANES = 6
#: Largest normal component (normals are directions; any non-zero length will do).
MAX_ABS_NORMAL = 1e6

_TOP_KEYS = {"type", "seq", "camera", "tf", "index", "width", "height", "preview", "format",
             "mode", "iso", "clip", "labels", "time"}
_CLIP_KEYS = {"box", "planes", "cap"}
_LABEL_KEYS = {"visible", "colors", "smooth"}
_CAMERA_KEYS = {"azimuth", "elevation", "zoom", "pan"}
_CAMERA_REQUIRED = ("azimuth", "elevation", "zoom")
PAN_LIMIT = 5.0  # bounding-sphere radii
_TF_KEYS = {"points", "colormap", "value_range"}
_INDEX_KEYS = {"name", "cell"}
_FORMATS = ("jpeg", "png")


class MessageError(ParameterError):
    """A client message that is not valid; the reply names the field."""


@dataclass(frozen=True)
class CameraSpec:
    azimuth: float = 30.0
    elevation: float = 20.0
    zoom: float = 1.0
    pan: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class TFSpec:
    """Normalised control points, optional colour map, data range (hashable: a cache key)."""

    points: tuple[tuple[float, float, float, float, float], ...]
    colormap: str | None
    value_range: tuple[float, float]


@dataclass(frozen=True)
class IndexSpec:
    name: str = "naive"
    cell: int | None = None


@dataclass(frozen=True)
class ClipSpec:
    """Clip box and planes in fractions of the volume's box, and capping (hashable).

    ``box`` is ``((x0, y0, z0), (x1, y1, z1))`` with ``0 <= lo <= hi <= 1`` per axis;
    each plane is ``(px, py, pz, nx, ny, nz)``: a point in box fractions and a
    non-zero normal along the world axes (the side it points to is kept).
    """

    box: tuple[tuple[float, float, float], tuple[float, float, float]] = ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    planes: tuple[tuple[float, float, float, float, float, float], ...] = ()
    #: shade the cut faces with their normals (``render(clip_cap=True)``; DVR only)
    cap: bool = False

    @property
    def is_full(self) -> bool:
        """Whether this clips nothing (the whole box, no plane)."""
        return self.box == FULL_CLIP.box and not self.planes


FULL_CLIP = ClipSpec()


@dataclass(frozen=True)
class LabelSpec:
    """A label-table edit: ``visible`` ids (``None``: unchanged), colour overrides
    ``(id, r, g, b, a)`` and smooth boundaries on or off."""

    visible: tuple[int, ...] | None = None
    colors: tuple[tuple[int, float, float, float, float], ...] = ()
    #: smooth boundaries from interpolated per-label masks (``None``: unchanged)
    smooth: bool | None = None


@dataclass(frozen=True)
class RenderRequest:
    """One validated client message; ``None`` sections leave the state unchanged."""

    seq: int = 0
    camera: CameraSpec | None = None
    tf: TFSpec | None = None
    index: IndexSpec | None = None
    width: int | None = None
    height: int | None = None
    preview: bool = False
    format: str = "jpeg"
    mode: str | None = None
    iso: tuple[float, ...] | None = None
    clip: ClipSpec | None = None
    labels: LabelSpec | None = None
    time: int | None = None


def _fail(msg: str) -> MessageError:
    return MessageError(msg)


def _number(value: Any, name: str, lo: float | None = None, hi: float | None = None) -> float:
    # bool is an int subclass; reject it explicitly.
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail(f"{name}: expected a number, got {type(value).__name__}")
    try:
        v = float(value)
    except OverflowError:  # huge JSON integers
        raise _fail(f"{name}: number out of range") from None
    if not math.isfinite(v):
        raise _fail(f"{name}: expected a finite number, got {v}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise _fail(f"{name}: expected a number in [{lo:g}, {hi:g}], got {v:g}")
    return v


def _integer(value: Any, name: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        # Accept integral floats (JavaScript has only doubles).
        if isinstance(value, float) and math.isfinite(value) and value.is_integer():
            value = int(value)
        else:
            raise _fail(f"{name}: expected an integer, got {type(value).__name__}")
    if not lo <= value <= hi:
        raise _fail(f"{name}: expected an integer in [{lo}, {hi}], got {value}")
    return int(value)


def _object(value: Any, name: str, keys: set[str]) -> dict:
    if not isinstance(value, dict):
        raise _fail(f"{name}: expected an object, got {type(value).__name__}")
    unknown = sorted(set(value) - keys)
    if unknown:
        shown = ", ".join(repr(k[:_MAX_NAME]) for k in unknown[:5])
        raise _fail(f"{name}: unknown key(s) {shown}; expected only {', '.join(sorted(keys))}")
    return value


def _name(value: Any, name: str, allowed: Iterable[str]) -> str:
    allowed = list(allowed)
    if not isinstance(value, str):
        raise _fail(f"{name}: expected a string, got {type(value).__name__}")
    if value not in allowed:
        shown = value[:_MAX_NAME] + ("..." if len(value) > _MAX_NAME else "")
        raise _fail(f"{name}: unknown {shown!r}; expected one of {', '.join(allowed)}")
    return value


def parse_camera(value: Any) -> CameraSpec:
    d = _object(value, "camera", _CAMERA_KEYS)
    for key in _CAMERA_REQUIRED:
        if key not in d:
            raise _fail(f"camera.{key}: missing")
    az = _number(d["azimuth"], "camera.azimuth", -MAX_ABS_AZIMUTH, MAX_ABS_AZIMUTH)
    el = _number(d["elevation"], "camera.elevation", -90.0, 90.0)
    zoom = _number(d["zoom"], "camera.zoom", *ZOOM_RANGE)
    pan = (0.0, 0.0)
    if "pan" in d:
        p = d["pan"]
        if not isinstance(p, list) or len(p) != 2:
            raise _fail(f"camera.pan: expected [right, up], got {type(p).__name__}")
        pan = (_number(p[0], "camera.pan[0]", -PAN_LIMIT, PAN_LIMIT),
               _number(p[1], "camera.pan[1]", -PAN_LIMIT, PAN_LIMIT))
    return CameraSpec(az % 360.0, el, zoom, pan)


def parse_tf(value: Any, presets: Iterable[str]) -> TFSpec:
    d = _object(value, "tf", _TF_KEYS)
    for key in sorted(_TF_KEYS):
        if key not in d:
            raise _fail(f"tf.{key}: missing")
    pts = d["points"]
    if not isinstance(pts, list):
        raise _fail(f"tf.points: expected a list of [x, r, g, b, a], got {type(pts).__name__}")
    if not 1 <= len(pts) <= MAX_TF_POINTS:
        raise _fail(f"tf.points: expected 1..{MAX_TF_POINTS} points, got {len(pts)}")
    out = []
    for i, p in enumerate(pts):
        if not isinstance(p, list) or len(p) != 5:
            raise _fail(f"tf.points[{i}]: expected [x, r, g, b, a]")
        out.append(tuple(_number(v, f"tf.points[{i}][{j}]", 0.0, 1.0) for j, v in enumerate(p)))
    out.sort(key=lambda p: p[0])  # stable: equal x keep their order (steps)
    cmap = d["colormap"]
    if cmap is not None:
        cmap = _name(cmap, "tf.colormap", presets)
    vr = d["value_range"]
    if not isinstance(vr, list) or len(vr) != 2:
        raise _fail("tf.value_range: expected [lo, hi]")
    lo = _number(vr[0], "tf.value_range[0]", -MAX_ABS_VALUE, MAX_ABS_VALUE)
    hi = _number(vr[1], "tf.value_range[1]", -MAX_ABS_VALUE, MAX_ABS_VALUE)
    if not lo < hi:
        raise _fail(f"tf.value_range: expected lo < hi, got [{lo:g}, {hi:g}]")
    return TFSpec(tuple(out), cmap, (lo, hi))


def parse_index(value: Any, indices: Iterable[str]) -> IndexSpec:
    d = _object(value, "index", _INDEX_KEYS)
    if "name" not in d:
        raise _fail("index.name: missing")
    name = _name(d["name"], "index.name", indices)
    cell = d.get("cell")
    if cell is not None:
        cell = _integer(cell, "index.cell", min(CELL_SIZES), max(CELL_SIZES))
        if cell not in CELL_SIZES:
            raise _fail(f"index.cell: expected one of {', '.join(map(str, CELL_SIZES))}, got {cell}")
    return IndexSpec(name, cell)


def _list(value: Any, name: str, lo: int, hi: int, what: str) -> list:
    if not isinstance(value, list):
        raise _fail(f"{name}: expected a list of {what}, got {type(value).__name__}")
    if not lo <= len(value) <= hi:
        raise _fail(f"{name}: expected {lo}..{hi} {what}, got {len(value)}")
    return value


def parse_iso(value: Any) -> tuple[float, ...]:
    """Isovalues in data units: a number or a list of 1..:data:`MAX_ISOVALUES` numbers."""
    values = value if isinstance(value, list) else [value]
    _list(values, "iso", 1, MAX_ISOVALUES, "isovalues")
    return tuple(_number(v, f"iso[{i}]", -MAX_ABS_VALUE, MAX_ABS_VALUE) for i, v in enumerate(values))


def parse_clip(value: Any) -> ClipSpec:
    d = _object(value, "clip", _CLIP_KEYS)
    box = FULL_CLIP.box
    if "box" in d:
        b = d["box"]
        if not (isinstance(b, list) and len(b) == 2 and all(isinstance(c, list) and len(c) == 3 for c in b)):
            raise _fail("clip.box: expected [[x0, y0, z0], [x1, y1, z1]] (fractions of the volume box)")
        lo, hi = (tuple(_number(v, f"clip.box[{c}][{j}]", 0.0, 1.0) for j, v in enumerate(b[c])) for c in (0, 1))
        for j, axis in enumerate("xyz"):
            if lo[j] > hi[j]:
                raise _fail(f"clip.box: expected {axis}0 <= {axis}1, got {lo[j]:g} > {hi[j]:g}")
        box = (lo, hi)
    planes = []
    for i, p in enumerate(_list(d.get("planes", []), "clip.planes", 0, MAX_CLIP_PLANES, "planes")):
        if not isinstance(p, list) or len(p) != 6:
            raise _fail(f"clip.planes[{i}]: expected [px, py, pz, nx, ny, nz]")
        point = [_number(v, f"clip.planes[{i}][{j}]", 0.0, 1.0) for j, v in enumerate(p[:3])]
        normal = [_number(v, f"clip.planes[{i}][{j + 3}]", -MAX_ABS_NORMAL, MAX_ABS_NORMAL)
                  for j, v in enumerate(p[3:])]
        if not any(normal):
            raise _fail(f"clip.planes[{i}]: expected a non-zero normal, got [0, 0, 0]")
        planes.append((*point, *normal))
    cap = d.get("cap", False)
    if not isinstance(cap, bool):
        raise _fail(f"clip.cap: expected true or false, got {cap!r}")
    return ClipSpec(box, tuple(planes), cap)  # type: ignore[arg-type]


def _label_id(value: Any, name: str, known: frozenset[int]) -> int:
    i = _integer(value, name, -(2**53), 2**53)
    if i not in known:
        raise _fail(f"{name}: id {i} does not occur in the label volume ({len(known)} ids)")
    return i


def parse_labels(value: Any, label_ids: Iterable[int] | None) -> LabelSpec:
    if label_ids is None:
        raise _fail("labels: this viewer does not show a label volume (start it with a label TF, "
                    "e.g. sparsecast view FILE --tf labels)")
    known = frozenset(int(i) for i in label_ids)
    d = _object(value, "labels", _LABEL_KEYS)
    visible = None
    if "visible" in d:
        ids = _list(d["visible"], "labels.visible", 0, len(known), "label ids")
        visible = tuple(sorted({_label_id(v, f"labels.visible[{i}]", known) for i, v in enumerate(ids)}))
    colors = []
    for i, c in enumerate(_list(d.get("colors", []), "labels.colors", 0, len(known), "colours")):
        if not isinstance(c, list) or len(c) != 5:
            raise _fail(f"labels.colors[{i}]: expected [id, r, g, b, a]")
        colors.append((_label_id(c[0], f"labels.colors[{i}][0]", known),
                       *(_number(v, f"labels.colors[{i}][{j + 1}]", 0.0, 1.0) for j, v in enumerate(c[1:]))))
    smooth = d.get("smooth")
    if smooth is not None and not isinstance(smooth, bool):
        raise _fail(f"labels.smooth: expected true or false, got {smooth!r}")
    return LabelSpec(visible, tuple(colors), smooth)  # type: ignore[arg-type]


def parse_time(value: Any, steps: int) -> int:
    if steps <= 0:
        raise _fail("time: this viewer shows one volume, not a time series")
    return _integer(value, "time", 0, steps - 1)


def parse_message(raw: str | bytes | None, *, indices: Iterable[str], presets: Iterable[str],
                  label_ids: Iterable[int] | None = None, steps: int = 0) -> RenderRequest:
    """Validate one client message; raise :class:`MessageError` when it is not acceptable.

    Parameters
    ----------
    raw : str
        The WebSocket text message.
    indices, presets : iterable of str
        Accepted index names and TF presets.
    label_ids : iterable of int, optional
        The ids of the label volume shown; ``None``: not a label volume (``labels`` is
        refused, ``mode`` must be ``dvr``).
    steps : int
        Time steps of the series shown; 0: one volume (``time`` is refused).
    """
    if raw is None:
        raise _fail("message: expected a JSON text message")
    if isinstance(raw, (bytes, bytearray)):
        raise _fail("message: binary messages are not accepted; send JSON text")
    if not isinstance(raw, str):
        raise _fail(f"message: expected JSON text, got {type(raw).__name__}")
    if len(raw) > MAX_MESSAGE_BYTES or len(raw.encode("utf-8", "replace")) > MAX_MESSAGE_BYTES:
        raise _fail(f"message: larger than {MAX_MESSAGE_BYTES} bytes")

    def _no_constants(c: str):
        raise _fail(f"message: {c} is not valid JSON")

    try:
        data = json.loads(raw, parse_constant=_no_constants)
    except MessageError:
        raise
    except (ValueError, RecursionError) as exc:
        raise _fail(f"message: not valid JSON ({str(exc)[:80]})") from None
    d = _object(data, "message", _TOP_KEYS)
    if d.get("type") != "render":
        t = d.get("type")
        shown = repr(t[:_MAX_NAME]) if isinstance(t, str) else type(t).__name__
        raise _fail(f"type: expected 'render', got {shown}")
    seq = _integer(d.get("seq", 0), "seq", 0, 2**53)
    camera = parse_camera(d["camera"]) if "camera" in d else None
    if "tf" in d and label_ids is not None:
        raise _fail("tf: a label volume is coloured per id; send labels {visible, colors} instead")
    tf = parse_tf(d["tf"], presets) if "tf" in d else None
    index = parse_index(d["index"], indices) if "index" in d else None
    width = _integer(d["width"], "width", MIN_SIDE, MAX_SIDE) if "width" in d else None
    height = _integer(d["height"], "height", MIN_SIDE, MAX_SIDE) if "height" in d else None
    preview = d.get("preview", False)
    if not isinstance(preview, bool):
        raise _fail(f"preview: expected true or false, got {type(preview).__name__}")
    fmt = _name(d.get("format", "jpeg"), "format", _FORMATS)
    mode = _name(d["mode"], "mode", MODES) if "mode" in d else None
    if mode not in (None, "dvr") and label_ids is not None:
        raise _fail(f"mode: {mode!r} needs a scalar field; a label volume renders with mode 'dvr'")
    iso = parse_iso(d["iso"]) if "iso" in d else None
    clip = parse_clip(d["clip"]) if "clip" in d else None
    labels = parse_labels(d["labels"], label_ids) if "labels" in d else None
    time_step = parse_time(d["time"], steps) if "time" in d else None
    return RenderRequest(seq, camera, tf, index, width, height, preview, fmt, mode, iso, clip, labels, time_step)


def frame_size(req_w: int | None, req_h: int | None, preview: bool) -> tuple[int, int]:
    """The image size to render: the client's canvas (default 512 x 512), capped at
    :data:`MAX_SIDE`; previews scaled down to fit :data:`PREVIEW_SIDE`, aspect kept."""
    w = FULL_SIDE if req_w is None else req_w
    h = FULL_SIDE if req_h is None else req_h
    w, h = min(w, MAX_SIDE), min(h, MAX_SIDE)
    if preview:
        s = min(1.0, PREVIEW_SIDE / max(w, h))
        w, h = max(MIN_SIDE, int(round(w * s))), max(MIN_SIDE, int(round(h * s)))
    return w, h
