"""yt's volume rendering (``yt.create_scene`` with a ``VolumeSource``), headless.

Mapping of a sparsecast case onto yt:

- volume: a uniform grid (``yt.load_uniform_grid``) indexed ``[x, y, z]`` whose
  cells are centred on our samples (bounding box half a voxel beyond our domain);
- TF: a ``ColorTransferFunction`` with grey opacity and one bin per entry of our
  table, linear scale; yt treats values on its bounds and 0.0 as transparent where
  we clamp, so the data are shifted by a constant and the table padded by one
  clamped entry per side;
- opacity: yt integrates emission-absorption, ``rgba = dt e + (1 - dt a) rgba``
  with ``dt`` in units of the ray parameter, and weights the colour by ``a``. Our
  sample opacity ``a`` per ``unit_distance`` is an extinction
  ``sigma = -ln(1 - a) / unit`` per world length; yt's ray vectors are
  ``max_length`` long (eye-to-centre distance plus half the domain diagonal),
  so its alpha table gets ``sigma * max_length``;
- step: yt takes a fixed number of samples per cell crossing (not a global
  lattice); we ask for ``ceil(spacing / dt)`` of them. A ray crossing cells of
  size ``s`` in direction ``d`` meets ``sum_i |d_i| / s_i`` cells per unit length
  (1/s along an axis, sqrt(3)/s on a diagonal), so yt takes up to ~1.7x our
  samples per unit length and no integer per-cell count can match ours on every
  view: :meth:`Scene.samples` estimates its sample count from the rays' cell
  crossings, and the benchmark reports it beside the time ratio;
- camera: perspective lens with the image plane at the target, sized to our
  vertical field of view (or plane-parallel with our orthographic height).

yt resamples cell data to vertices and steps per cell, so its image differs from
ours more than VTK's does: the benchmark reports the PSNR.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...camera import Camera
from ...transfer import TransferFunction
from ...volume import Volume

__all__ = ["NAME", "unavailable_reason", "Scene", "render"]

NAME = "yt"
_FIELD = ("stream", "values")


def unavailable_reason() -> str | None:
    """None when yt can volume-render here, otherwise why not."""
    try:
        import yt  # noqa: F401
    except ImportError as exc:
        return f"yt is not installed ({exc}); pip install 'sparsecast[peers]'"
    return None


class Scene:
    """A yt scene holding ``volume`` classified by ``tf``, ready to render."""

    def __init__(self, volume: Volume, tf: TransferFunction, dt: float) -> None:
        import yt

        yt.set_log_level(40)  # no per-frame INFO lines on stderr
        # yt's table look-up returns 0 for values on or outside its bounds and for any
        # value that is not a normal float (0.0 included), where our look-up clamps. So
        # yt gets the data shifted by a constant (no value is 0) and a table one entry
        # wider on each side, holding our end entries: the same TF as ours.
        lo, hi = tf.value_range
        self._step = (hi - lo) / (tf.table_size - 1)
        self._shift = (hi - lo) + 1.0 - lo
        data = np.ascontiguousarray(volume.data.transpose(2, 1, 0), dtype=np.float64) + self._shift  # [x, y, z]
        spacing = np.asarray(volume.spacing, np.float64)
        self._lo = np.asarray(volume.origin, np.float64) - 0.5 * spacing
        self._dims = np.array(volume.dims, np.float64)
        self._hi = self._lo + self._dims * spacing
        self._ds = yt.load_uniform_grid({"values": (data, "")}, data.shape,
                                        bbox=np.stack([self._lo, self._hi], axis=1), length_unit=1.0)
        self._tf = tf
        self._unit = tf.unit_distance if tf.unit_distance is not None else float(spacing.min())
        self._samples_per_cell = max(1, math.ceil(float(spacing.min()) / dt))
        self._scenes: dict[str, object] = {}

    def _scene(self, projection: str):
        """One yt scene per lens type (yt fixes the lens when the camera is made)."""
        import yt

        lens = "perspective" if projection == "perspective" else "plane-parallel"
        if lens not in self._scenes:
            scene = yt.create_scene(self._ds, _FIELD, lens_type=lens)
            scene[0].set_log(False)
            scene[0].num_samples = self._samples_per_cell
            self._scenes[lens] = scene
        return self._scenes[lens]

    def _transfer_function(self, ray_length: float):
        import yt

        tf = self._tf
        table = np.concatenate([tf.table[:1], tf.table, tf.table[-1:]]).astype(np.float64)  # clamped ends
        a = np.clip(table[:, 3], 0.0, 0.999)
        sigma = -np.log1p(-a) / self._unit  # extinction per world length
        lo, hi = tf.value_range
        bounds = (lo + self._shift - self._step, hi + self._shift + self._step)
        ytf = yt.ColorTransferFunction(bounds, nbins=len(table), grey_opacity=True)
        for channel in range(3):  # yt weights colour by the alpha table: emission = rgb * sigma
            ytf.funcs[channel].y[:] = table[:, channel]
        ytf.funcs[3].y[:] = sigma * ray_length
        return ytf

    def samples(self, camera: Camera, width: int, height: int) -> int:
        """yt's sample count for this frame, estimated: ``num_samples`` per cell crossed,
        cells crossed per ray = its chord through yt's domain times ``sum_i |d_i| / s_i``
        (+1 for the cell it enters). No early termination (yt has none)."""
        o, d = camera.rays(width, height)
        o, d = o.reshape(-1, 3), d.reshape(-1, 3)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / d
            ta, tb = (self._lo - o) * inv, (self._hi - o) * inv
        t0 = np.nanmax(np.minimum(ta, tb), axis=1).clip(min=0.0)
        t1 = np.nanmin(np.maximum(ta, tb), axis=1)
        chord = np.maximum(t1 - t0, 0.0)
        spacing = (self._hi - self._lo) / self._dims
        cells = chord * (np.abs(d) / spacing).sum(axis=1)
        cells = np.where(chord > 0, cells + 1.0, 0.0)
        return int(round(float(cells.sum()) * self._samples_per_cell))

    def render(self, camera: Camera, width: int, height: int) -> tuple[np.ndarray, float]:
        """One frame: ``(rgba, ms)``, rgba float32 (H, W, 4) premultiplied over black."""
        ds = self._ds
        scene = self._scene(camera.projection)
        cam = scene.camera
        cam.resolution = (int(width), int(height))
        eye, target = camera.eye, camera.target
        dist = float(np.linalg.norm(target - eye))
        if camera.projection == "perspective":
            h = 2.0 * dist * math.tan(math.radians(camera.fov_y) / 2.0)
        else:
            h = camera.ortho_height
        cam.set_width(ds.arr([h * width / height, h, dist], "code_length"))
        up = camera.basis()[2]
        cam.set_position(ds.arr(eye, "code_length"), north_vector=up)
        cam.focus = ds.arr(target, "code_length")
        cam.set_position(ds.arr(eye, "code_length"), north_vector=up)
        center = 0.5 * (self._lo + self._hi)
        ray_length = float(np.linalg.norm(eye - center) + 0.5 * np.linalg.norm(self._hi - self._lo))
        if camera.projection != "perspective":
            ray_length = dist  # plane-parallel rays span the camera depth
        scene[0].set_transfer_function(self._transfer_function(ray_length))
        t0 = time.perf_counter()
        image = np.asarray(scene.render())
        ms = (time.perf_counter() - t0) * 1e3
        # yt's image is indexed [column, row] (row 0 on top, as ours): transpose only.
        rgba = np.clip(image.transpose(1, 0, 2), 0.0, 1.0).astype(np.float32)
        rgba[..., 3] = 1.0  # composited over black
        return rgba, ms


def render(volume: Volume, tf: TransferFunction, camera: Camera, width: int, height: int,
           dt: float) -> tuple[np.ndarray, float]:
    """Render one frame with yt: ``(rgba, ms)`` (see :class:`Scene`)."""
    return Scene(volume, tf, dt).render(camera, width, height)
