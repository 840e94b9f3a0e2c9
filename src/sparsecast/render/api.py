"""``render()``: the one entry point for direct volume rendering, whatever the index
and wherever it runs (this process, or a Dask cluster)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..camera import Camera
from ..errors import ParameterError
from ..image import Image
from ..index import SpatialIndex
from ..transfer import TransferFunction
from ..volume import Volume
from .local import (
    MAX_CLIP_PLANES, MAX_SAMPLES_PER_IMAGE, MAX_SAMPLES_PER_RAY, classification_tf, render_local, same_emptiness,
)
from .options import DEFAULT_SHADING, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE

__all__ = ["render", "classification_tf", "same_emptiness", "MAX_IMAGE_SIDE", "MAX_IMAGE_PIXELS",
           "MAX_SAMPLES_PER_RAY", "MAX_CLIP_PLANES", "MAX_SAMPLES_PER_IMAGE", "DEFAULT_SHADING"]


def render(
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
    client: Any = None,
    pieces: int | None = None,
    cross_termination: bool = False,
    timeout: float | None = None,
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
        ``"auto"`` (default: chosen from the volume's brick occupancy under ``tf``,
        see :mod:`sparsecast.index.auto`; the choice is ``stats["index"]`` and its
        reason ``stats["auto"]``), an index name from :func:`available_indices`
        (built on the fly; its build time appears in ``stats["build_ms"]``), or a
        prebuilt index for this volume and TF, which is reused. An exact index built
        from a name is kept with the volume and serves the next frames while the TF
        leaves the same space empty (a camera path, a colour edit, a toggle between
        isosurface and DVR frames: ``stats["index_reused"]``, ``build_ms`` 0); see
        :mod:`sparsecast.render.reuse`.
    ert : float
        Early ray termination once accumulated opacity reaches this, in (0, 1];
        1.0 turns it off.
    shading : bool or mapping
        Gradient shading with a headlight (Blinn-Phong). ``True`` uses
        :data:`DEFAULT_SHADING`; a mapping overrides ``ka``, ``kd``, ``ks``, ``shininess``.
    background : str or sequence of 3-4 floats
        Straight RGB(A) in [0, 1] composited behind the volume, or one of
        ``transparent`` (default), ``black``, ``white``, ``gray``.
    clip_box : ((x0, y0, z0), (x1, y1, z1)), optional
        World-space box outside which no sample is taken (intersected with the
        volume's box). Default: the volume's box.
    clip_open : ((bool, bool, bool), (bool, bool, bool)), optional
        Faces of ``clip_box`` (lower x, y, z faces; upper x, y, z faces) that do
        not contain their plane: a sample exactly on an open face is not taken.
        Two boxes sharing a face, open in one and closed in the other, never both
        take a sample on it. Default: all closed.
    clip_planes : sequence of (point, normal), optional
        Up to :data:`MAX_CLIP_PLANES` world-space planes; each keeps the side its
        normal points to (``normal . (x - point) >= 0``). Combined with ``clip_box``.
    clip_cap : bool
        Shade the cut faces (what VTK and ParaView call capping): a ray that enters
        the clip region through a clip-box face inside the volume, or through a clip
        plane, lights its first sample there with the face's normal instead of the
        gradient (Blinn-Phong with ``shading``'s coefficients, or the defaults when
        the volume is unshaded). Rays entering through the volume's own faces, or
        starting inside the region, are unchanged; so is every sample after the
        first. Exact for every index (the cap sample is taken before traversal).
        ``mode="dvr"`` only.
    initial : (h, w, 4) float32, optional
        Premultiplied RGBA already accumulated in front of the clip box, per
        pixel of the rendered rectangle: rays continue from it (and stop at once
        where it reaches ``ert``).
    rect : (x0, y0, w, h), optional
        Render only this rectangle of the ``width`` x ``height`` image; the result
        is ``h`` x ``w``. Default: the whole image.
    max_samples : int
        Refuse a render that could take more lattice samples than this (pixels
        times samples across the volume's diagonal), before any work: a tiny
        ``dt`` is an error, not a render of many minutes. Default 2**33.
    mode : {"dvr", "iso", "iso+dvr"}
        ``"dvr"`` (default): direct volume rendering. ``"iso"``: the isosurfaces
        ``iso`` (first crossing between lattice samples, refined by bisection,
        shaded with the gradient; translucent surfaces show those behind them).
        ``"iso+dvr"``: both, composited in depth order. The iso modes skip empty
        space with bricks whose value range holds an isovalue (or, for iso+dvr, that
        the TF leaves non-empty), so every exact index equals naive here too; an
        isovalue outside the data range gives a background image. The BIH's
        build modes (``"ess"``, ``"single-sample"``, ``"multi-sample"``) are still
        passed on to ``index="bih"`` as before.
    iso : float or sequence of float
        Isovalues (1 to 8) for the iso modes, in data units.
    iso_colors : sequence of (r, g, b[, a]), optional
        Straight colour and opacity of each surface. Default: the TF's colour at
        the isovalue, opaque.
    client : dask.distributed.Client, optional
        Render on this Dask cluster instead of in this process (see
        :mod:`sparsecast.distributed`): the volume is cut into pieces on brick
        boundaries, each worker keeps its pieces across frames, renders its screen
        rectangle of each, and the pieces are composited front to back. The image
        equals the single-process one (<= 1e-5) with ``ert=1``, and with
        ``cross_termination=True`` at any ``ert``. ``stats`` adds ``pieces``,
        ``workers``, ``bytes_moved`` and per-phase milliseconds. DVR modes only (no
        iso modes, no ``clip_cap``), and ``index`` must be a name.
    pieces : int, optional
        With ``client``: how many pieces (default one per worker thread). The volume's
        pieces are kept for the next frame with the same count.
    cross_termination : bool
        With ``client``: render the pieces one after another in visibility order, each
        continuing from the opacity accumulated in front of it, so early ray
        termination stops rays across pieces exactly as in one process (slower on a
        cluster: the pieces no longer run at once). Default False: pieces run at once
        and each terminates on its own opacity, which differs from one process by at
        most ``1 - ert`` per channel.
    timeout : float, optional
        With ``client``: seconds a frame may take (default 300); a frame that does not
        complete in time raises :class:`~sparsecast.errors.DistributedError`, never a
        partial image.
    **index_options
        Passed to :func:`build_index` when ``index`` is a name (e.g. ``cell=16``
        for the grids).

    Returns
    -------
    Image
        Premultiplied float32 RGBA and ``stats``: ``ms`` (marching only), ``samples``,
        ``samples_nonempty``, ``rays``, ``build_ms`` (index built on the fly, 0 when
        ``index_reused``),
        ``jit_ms`` (one-off kernel compilation or cache load of the driver and of an
        index built on the fly, kept out of ``ms`` and ``build_ms``).

    Raises
    ------
    DistributedError
        With ``client``: the scheduler cannot be reached, or the frame did not
        complete in ``timeout`` (the client recovers for the next frame).
    VolumeDataError
        The volume has fewer than 2 voxels along an axis (see
        :meth:`Volume.require_renderable <sparsecast.volume.Volume.require_renderable>`).

    Notes
    -----
    Opacity correction ``1 - (1 - a) ** (dt / unit_distance)`` is applied to the TF
    table entries, which are then linearly interpolated; ``unit_distance`` is the
    TF's, or the smallest voxel spacing when the TF leaves it unset.
    """
    frame = dict(dt=dt, index=index, ert=ert, shading=shading, background=background, clip_box=clip_box,
                 clip_open=clip_open, clip_planes=clip_planes, clip_cap=clip_cap, initial=initial, rect=rect,
                 max_samples=max_samples, mode=mode, iso=iso, iso_colors=iso_colors, **index_options)
    if client is not None:
        # Imported here: the cluster renders its pieces with render_local, below this module.
        from ..distributed import render_on_cluster

        return render_on_cluster(client, volume, tf, camera, width, height, pieces=pieces,
                                 cross_termination=cross_termination, timeout=timeout, **frame)
    for name, value in (("pieces", pieces), ("timeout", timeout)):
        if value is not None:
            raise ParameterError(f"{name}: applies only with client= (a Dask cluster), got {value!r}")
    if cross_termination:
        raise ParameterError("cross_termination: applies only with client= (a Dask cluster)")
    return render_local(volume, tf, camera, width, height, **frame)
