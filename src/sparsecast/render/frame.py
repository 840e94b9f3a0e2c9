"""The per-frame record the DVR driver reads: camera, TF table, lattice, clip, screen rectangle."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..kernels.iso import Iso, IsoDvr
from ..kernels.march import Dvr
from ..kernels.sampler import Nearest, SmoothLabels, Trilinear

__all__ = ["Frame"]


class Frame(NamedTuple):
    """Everything the driver needs for one frame besides the index and the voxels.

    Built by :func:`sparsecast.render.render`; all arrays are C-contiguous and of
    the dtypes given, so one compiled driver serves every frame.

    Attributes
    ----------
    cam : (13,) float64
        :meth:`Camera.ray_params` for the full image.
    width, height : int
        Full image size (rays are generated for it).
    x0, y0 : int
        Top-left pixel of the rendered rectangle; the output arrays have the
        rectangle's size.
    origin, inv_spacing : (3,) float64
        World position of voxel (0, 0, 0) and ``1 / spacing`` (x, y, z).
    dt : float
        World-space lattice step.
    ert : float
        Early-ray-termination opacity.
    shading : (5,) float64
        See :mod:`sparsecast.kernels.shade`.
    background : (4,) float64
        Straight RGBA composited behind each pixel.
    table : (n, 4) float32
        Step-corrected TF table; ``v_lo``, ``scale`` map values onto it.
    clip_lo, clip_hi : (3,) float64
        Index-space clip box (already intersected with the volume box).
    open_lo, open_hi : (3,) bool
        Clip faces that exclude samples lying exactly on them.
    any_open : bool
        Whether any clip face is open.
    planes : (m, 4) float64
        Index-space clip half-spaces ``n . x >= c`` as rows ``(nx, ny, nz, c)``; m may be 0.
    cap : (5,) float64
        Shading of clip caps (:mod:`sparsecast.kernels.shade` layout); ``cap[0] == 0``:
        no caps. The first sample behind a cut face is lit with the face's normal.
    cut_lo, cut_hi : (3,) bool
        Clip-box faces that cut the volume (strictly inside its box): the faces that
        get caps (clip planes always do).
    sampler : Trilinear, Nearest or SmoothLabels
        How samples read and classify the voxels (:mod:`sparsecast.kernels.sampler`);
        its type selects the compiled marching loop.
    mode : Dvr, Iso or IsoDvr
        What a ray composites (:mod:`sparsecast.kernels.march`, :mod:`sparsecast.kernels.iso`):
        DVR samples, isosurfaces, or both in depth order; its type selects the loop too.
    """

    cam: np.ndarray
    width: int
    height: int
    x0: int
    y0: int
    origin: np.ndarray
    inv_spacing: np.ndarray
    dt: float
    ert: float
    shading: np.ndarray
    background: np.ndarray
    table: np.ndarray
    v_lo: float
    scale: float
    clip_lo: np.ndarray
    clip_hi: np.ndarray
    open_lo: np.ndarray
    open_hi: np.ndarray
    any_open: bool
    planes: np.ndarray
    cap: np.ndarray
    cut_lo: np.ndarray
    cut_hi: np.ndarray
    sampler: Trilinear | Nearest | SmoothLabels
    mode: Dvr | Iso | IsoDvr
