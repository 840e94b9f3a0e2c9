"""Render a surface index from a :class:`~sparsecast.Camera`: shaded, depth or normal images."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..errors import ParameterError
from ..image import Image
from .index import SurfaceIndex
from .secondary import facing

__all__ = ["render_surface", "cast_camera", "PixelHits", "shade"]

MODES = ("shaded", "depth", "normal")
#: grey material of the shaded mode: ambient + diffuse headlight
AMBIENT, DIFFUSE, ALBEDO = 0.15, 0.85, 0.8


@dataclass(frozen=True)
class PixelHits:
    """Per-pixel closest hits of a camera's primary rays (``t = inf`` for misses)."""

    t: np.ndarray  # (H, W) float64
    normals: np.ndarray  # (H, W, 3) float32
    face: np.ndarray  # (H, W) int32
    tile: np.ndarray  # (H, W) int32
    uv: np.ndarray  # (H, W, 2) float32
    ms: float


def cast_camera(index: SurfaceIndex, camera: Camera, width: int, height: int) -> PixelHits:
    """Trace one primary ray per pixel (parallel over pixel tiles) and time it."""
    if not isinstance(index, SurfaceIndex):
        raise ParameterError(f"index: expected a SurfaceIndex from build_bvh/build_rbvh, got {type(index).__name__}")
    if not isinstance(camera, Camera):
        raise ParameterError(f"camera: expected a sparsecast.Camera, got {type(camera).__name__}")
    if not (isinstance(width, (int, np.integer)) and isinstance(height, (int, np.integer)) and width > 0 and height > 0):
        raise ParameterError(f"width, height: expected positive integers, got {width!r}, {height!r}")
    params = camera.ray_params(width, height)
    t = np.empty((height, width), np.float64)
    nrm = np.empty((height, width, 3), np.float32)
    face = np.empty((height, width), np.int32)
    tile = np.empty((height, width), np.int32)
    uv = np.empty((height, width, 2), np.float32)
    kernel, args = index.primary_call(params, width, height, (t, nrm, face, tile, uv))
    t0 = time.perf_counter()
    kernel(*args)
    ms = (time.perf_counter() - t0) * 1e3
    return PixelHits(t, nrm, face, tile, uv, ms)


def shade(hits: PixelHits, camera: Camera, mode: str, depth_range: tuple[float, float],
          background=(0.0, 0.0, 0.0, 1.0)) -> np.ndarray:
    """Premultiplied RGBA (H, W, 4) of the hits over a straight-RGBA ``background``."""
    if mode not in MODES:
        raise ParameterError(f"mode: expected one of {MODES}, got {mode!r}")
    h, w = hits.t.shape
    _, d = camera.rays(w, h)
    hit = np.isfinite(hits.t)
    # Two-sided: turn every normal towards the viewer.
    n = facing(hits.normals, d)
    if mode == "shaded":
        c = ALBEDO * (AMBIENT + DIFFUSE * np.abs(np.sum(n * d, axis=-1)))
        rgb = np.repeat(c[..., None], 3, axis=-1)
    elif mode == "normal":
        rgb = 0.5 + 0.5 * n
    else:
        near, far = depth_range
        c = 1.0 - np.clip((hits.t - near) / max(far - near, 1e-12), 0.0, 1.0)
        rgb = np.repeat(np.where(hit, c, 0.0)[..., None], 3, axis=-1)
    bg = np.asarray(background, dtype=np.float64)
    out = np.empty((h, w, 4), np.float32)
    out[..., :3] = np.where(hit[..., None], rgb, bg[:3] * bg[3])
    out[..., 3] = np.where(hit, 1.0, bg[3])
    return out


def render_surface(index: SurfaceIndex, camera: Camera, width: int = 512, height: int = 512, *,
                   mode: str = "shaded", background=(0.0, 0.0, 0.0, 1.0)) -> Image:
    """Ray cast ``index`` from ``camera`` into an :class:`~sparsecast.image.Image`.

    Parameters
    ----------
    index : SurfaceIndex
        From :func:`build_bvh` or :func:`build_rbvh`.
    camera : Camera
        E.g. ``Camera.orbit(mesh, 30, 20)`` (meshes frame like volumes).
    mode : {"shaded", "depth", "normal"}
        Grey headlight shading; depth (white = near) over the index's bounding
        sphere; or the world normal mapped to RGB.
    background : straight RGBA of pixels without a hit.

    Returns
    -------
    Image
        ``stats``: ``ms`` (ray casting), ``rays``, ``hits``, ``mrays_s``, ``index``, ``mode``.
    """
    if mode not in MODES:
        raise ParameterError(f"mode: expected one of {MODES}, got {mode!r}")
    bg = np.asarray(background, dtype=np.float64)
    if bg.shape != (4,) or not np.all((bg >= 0) & (bg <= 1)):
        raise ParameterError(f"background: expected straight RGBA in [0, 1], got {background!r}")
    # Compile / load the kernel on one pixel first so ms excludes JIT time.
    cast_camera(index, camera, 1, 1)
    hits = cast_camera(index, camera, width, height)
    dist = float(np.linalg.norm(camera.eye - index.center))
    radius = 0.5 * index.diagonal
    rgba = shade(hits, camera, mode, (max(dist - radius, 0.0), dist + radius), bg)
    n_hits = int(np.isfinite(hits.t).sum())
    rays = width * height
    stats = {"ms": hits.ms, "rays": rays, "hits": n_hits, "samples": rays,
             "mrays_s": rays / max(hits.ms, 1e-9) / 1e3, "index": index.kind, "mode": mode,
             "width": width, "height": height}
    return Image(rgba, stats)
