"""``render()``: the one entry point for direct volume rendering, whatever the index."""

from __future__ import annotations

import time
from dataclasses import replace
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..camera import Camera
from ..errors import ParameterError
from ..index import SpatialIndex, build_index
from ..kernels.shade import SHADING_SIZE
from ..transfer import TransferFunction
from ..volume import Volume
from .image import Image
from .setup import RenderSetup, marcher_for

__all__ = ["render", "MAX_IMAGE_SIDE", "MAX_IMAGE_PIXELS", "DEFAULT_SHADING"]

MAX_IMAGE_SIDE = 16384
MAX_IMAGE_PIXELS = 1 << 26  # 64 Mpixel: 1 GiB of float RGBA
MAX_SAMPLES_PER_RAY = 1 << 22

#: Blinn-Phong coefficients used by ``shading=True``.
DEFAULT_SHADING: dict[str, float] = {"ka": 0.3, "kd": 0.7, "ks": 0.25, "shininess": 24.0}

_NAMED_BACKGROUNDS = {
    "transparent": (0.0, 0.0, 0.0, 0.0),
    "black": (0.0, 0.0, 0.0, 1.0),
    "white": (1.0, 1.0, 1.0, 1.0),
    "gray": (0.5, 0.5, 0.5, 1.0),
}


def render(
    volume: Volume,
    tf: TransferFunction,
    camera: Camera,
    width: int = 512,
    height: int = 512,
    *,
    dt: float | None = None,
    index: str | SpatialIndex = "naive",
    ert: float = 0.99,
    shading: bool | Mapping[str, float] = False,
    background: str | Sequence[float] = "transparent",
    **index_options: Any,
) -> Image:
    """Direct volume rendering of ``volume`` classified by ``tf`` as seen by ``camera``.

    Every index samples the same global lattice ``t_k = k * dt`` along each ray, so
    exact empty-space-skipping indices return the same image as ``index="naive"``.

    Parameters
    ----------
    volume : Volume
    tf : TransferFunction
    camera : Camera
    width, height : int
        Image size in pixels, each 1..16384 and at most 64 Mpixel in all.
    dt : float, optional
        World-space distance between samples. Default: half the smallest voxel spacing.
    index : str or SpatialIndex
        An index name from :func:`available_indices` (built on the fly; its build
        time appears in ``stats["build_ms"]``), or a prebuilt index for this volume
        and TF, which is reused.
    ert : float
        Early ray termination once accumulated opacity reaches this, in (0, 1];
        1.0 turns it off.
    shading : bool or mapping
        Gradient shading with a headlight (Blinn-Phong). ``True`` uses
        :data:`DEFAULT_SHADING`; a mapping overrides ``ka``, ``kd``, ``ks``, ``shininess``.
    background : str or sequence of 3-4 floats
        Straight RGB(A) in [0, 1] composited behind the volume, or one of
        ``transparent`` (default), ``black``, ``white``, ``gray``.
    **index_options
        Passed to :func:`build_index` when ``index`` is a name (e.g. ``cell=16``
        for the grids).

    Returns
    -------
    Image
        Premultiplied float32 RGBA and ``stats``: ``ms`` (marching only), ``samples``,
        ``samples_nonempty``, ``rays``, ``build_ms`` (index built on the fly),
        ``jit_ms`` (one-off kernel compilation or cache load, kept out of ``ms``).

    Notes
    -----
    Opacity correction ``1 - (1 - a) ** (dt / unit_distance)`` is applied to the TF
    table entries, which are then linearly interpolated; ``unit_distance`` is the
    TF's, or the smallest voxel spacing when the TF leaves it unset.
    """
    if isinstance(volume, np.ndarray):
        volume = Volume(volume)
    if not isinstance(volume, Volume):
        raise ParameterError(f"volume: expected a sparsecast.Volume, got {type(volume).__name__}")
    if not isinstance(tf, TransferFunction):
        raise ParameterError(f"tf: expected a sparsecast.TransferFunction, got {type(tf).__name__}")
    if not isinstance(camera, Camera):
        raise ParameterError(f"camera: expected a sparsecast.Camera, got {type(camera).__name__}")
    width, height = _check_size(width, height)
    min_spacing = float(volume.spacing.min())
    if dt is None:
        dt = 0.5 * min_spacing
    dt = _as_float(dt, "dt")
    if not (np.isfinite(dt) and dt > 0):
        raise ParameterError(f"dt: expected a positive world-space step, got {dt}")
    if volume.diagonal / dt > MAX_SAMPLES_PER_RAY:
        raise ParameterError(
            f"dt: {dt:g} would take {volume.diagonal / dt:.3g} samples per ray across the volume; "
            f"expected at most {MAX_SAMPLES_PER_RAY} (dt >= {volume.diagonal / MAX_SAMPLES_PER_RAY:.3g})"
        )
    ert = _as_float(ert, "ert")
    if not (0.0 < ert <= 1.0):
        raise ParameterError(f"ert: expected an opacity threshold in (0, 1], got {ert}")

    build_ms = 0.0
    if isinstance(index, str):
        index = build_index(volume, tf, index, **index_options)
        build_ms = index.build_ms
    elif isinstance(index, SpatialIndex):
        if index_options:
            raise ParameterError(
                f"index options {sorted(index_options)} apply only when index is a name; "
                "this index is already built"
            )
        if index.volume is not volume or index.tf is not tf:
            raise ParameterError(
                f"index: this {index.name!r} index was built for another volume or transfer function; "
                "build a new one with build_index(volume, tf, name)"
            )
    else:
        raise ParameterError(f"index: expected an index name or a SpatialIndex, got {type(index).__name__}")

    unit = tf.unit_distance if tf.unit_distance is not None else min_spacing
    setup = RenderSetup(
        width=width,
        height=height,
        cam=camera.ray_params(width, height),
        table=tf.opacity_table(dt, unit),
        v_lo=float(tf.value_range[0]),
        scale=float(tf.scale),
        origin=np.ascontiguousarray(volume.origin, dtype=np.float64),
        inv_spacing=1.0 / volume.spacing,
        dt=dt,
        ert=ert,
        shading=_shading_array(shading),
        background=_background_array(background),
        rgba=np.empty((height, width, 4), np.float32),
        samples=np.empty((height, width), np.int32),
        nonempty=np.empty((height, width), np.int32),
    )
    marcher = marcher_for(index.name)
    jit_ms = _warm_up(marcher, index, setup, camera)
    t0 = time.perf_counter()
    marcher(index, setup)
    ms = (time.perf_counter() - t0) * 1e3
    samples = int(setup.samples.sum(dtype=np.int64))
    stats: dict[str, Any] = {
        "ms": ms,
        "samples": samples,
        "samples_nonempty": int(setup.nonempty.sum(dtype=np.int64)),
        "rays": width * height,
        "msamples_per_s": samples / ms / 1e3 if ms > 0 else float("nan"),
        "index": index.name,
        "build_ms": build_ms,
        "jit_ms": jit_ms,
        "width": width,
        "height": height,
        "dt": dt,
        "ert": ert,
        "shading": bool(setup.shading[0]),
    }
    return Image(setup.rgba, stats, setup.samples)


_WARM: set[tuple] = set()


def _warm_up(marcher, index, setup: RenderSetup, camera: Camera) -> float:
    """Compile (or load from the on-disk cache) the marcher for these argument types
    by rendering one pixel, so that ``stats["ms"]`` never includes JIT time.

    Returns the milliseconds spent, 0 when this combination was already warm.
    """
    key = (index.name, index.volume.data.dtype.str)
    if key in _WARM:
        return 0.0
    t0 = time.perf_counter()
    tiny = replace(
        setup, width=1, height=1, cam=camera.ray_params(1, 1),
        rgba=np.empty((1, 1, 4), np.float32), samples=np.empty((1, 1), np.int32),
        nonempty=np.empty((1, 1), np.int32),
    )
    marcher(index, tiny)
    _WARM.add(key)
    return (time.perf_counter() - t0) * 1e3


def _as_float(value, name: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name}: expected a number, got {value!r}") from None


def _check_size(width, height) -> tuple[int, int]:
    out = []
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise ParameterError(f"{name}: expected an integer number of pixels, got {v!r}")
        v = int(v)
        if not 1 <= v <= MAX_IMAGE_SIDE:
            raise ParameterError(f"{name}: expected 1..{MAX_IMAGE_SIDE} pixels, got {v}")
        out.append(v)
    if out[0] * out[1] > MAX_IMAGE_PIXELS:
        raise ParameterError(
            f"image size: {out[0]}x{out[1]} is {out[0] * out[1]} pixels; expected at most {MAX_IMAGE_PIXELS}"
        )
    return out[0], out[1]


def _shading_array(shading) -> np.ndarray:
    arr = np.zeros(SHADING_SIZE, np.float64)
    if shading is False or shading is None:
        return arr
    params = dict(DEFAULT_SHADING)
    if isinstance(shading, Mapping):
        unknown = set(shading) - set(params)
        if unknown:
            raise ParameterError(f"shading: unknown keys {sorted(unknown)}; expected {sorted(params)}")
        params.update({k: float(v) for k, v in shading.items()})
    elif shading is not True:
        raise ParameterError(f"shading: expected a bool or a mapping, got {shading!r}")
    for k, v in params.items():
        if not (np.isfinite(v) and v >= 0):
            raise ParameterError(f"shading[{k!r}]: expected a non-negative number, got {v}")
    arr[:] = (1.0, params["ka"], params["kd"], params["ks"], params["shininess"])
    return arr


def _background_array(background) -> np.ndarray:
    if isinstance(background, str):
        try:
            return np.array(_NAMED_BACKGROUNDS[background.lower()], np.float64)
        except KeyError:
            raise ParameterError(
                f"background: unknown colour {background!r}; expected one of {sorted(_NAMED_BACKGROUNDS)} "
                "or 3-4 numbers in [0, 1]"
            ) from None
    arr = np.asarray(background, dtype=np.float64).ravel()
    if arr.size == 3:
        arr = np.append(arr, 1.0)
    if arr.size != 4 or not np.all((arr >= 0) & (arr <= 1)):
        raise ParameterError(f"background: expected 3-4 numbers in [0, 1], got {background!r}")
    return arr
