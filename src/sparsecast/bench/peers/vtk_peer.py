"""VTK's CPU ray caster (``vtkFixedPointVolumeRayCastMapper``), rendered offscreen.

Mapping of a sparsecast case onto VTK:

- volume: ``vtkImageData`` with dimensions ``(nx, ny, nz)``, the same spacing and
  origin; our C-ordered ``(nz, ny, nx)`` array raveled is exactly VTK's x-fastest
  point order (shared, not copied);
- TF: every entry of the baked table becomes a point of a
  ``vtkColorTransferFunction`` / ``vtkPiecewiseFunction`` (both piecewise linear and
  clamped outside the range, as our lookup is);
- opacity correction: VTK's scalar-opacity unit distance is our ``unit_distance``
  (default the smallest spacing) and its sample distance is our ``dt``, so both
  apply ``1 - (1 - a) ** (dt / unit)``; automatic sample-distance adjustment is off;
- camera: eye, target, up and vertical field of view (or parallel scale) as ours;
- threads: as many as Numba uses, so the two run on the same cores.

VTK quantises scalars to 15 bits and terminates rays near full opacity, so its
image is close to ours, not equal: the benchmark reports the PSNR.
"""

from __future__ import annotations

import os
import time

import numpy as np

from ...camera import Camera
from ...transfer import TransferFunction
from ...volume import Volume

__all__ = ["NAME", "unavailable_reason", "Scene", "render", "load_vtk", "volume_property", "set_camera", "read_rgba"]

NAME = "vtk"


def unavailable_reason() -> str | None:
    """None when VTK can render offscreen here, otherwise why not."""
    try:
        load_vtk()
    except ImportError as exc:
        return f"vtk is not installed ({exc}); pip install 'sparsecast[peers]'"
    return None


def load_vtk():
    """``(vtkmodules.all, numpy_support)``, asking for an EGL window on a headless machine."""
    # Headless machines have no X server: ask for EGL (or OSMesa) before VTK picks.
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import vtkmodules.all as vtk  # noqa: F401  (loads every rendering backend)
    from vtkmodules.util import numpy_support

    vtk.vtkObject.GlobalWarningDisplayOff()
    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_ERROR)
    return vtk, numpy_support


def volume_property(vtk, volume: Volume, tf: TransferFunction):
    """A ``vtkVolumeProperty`` holding ``tf``'s baked table: one point per entry of a
    ``vtkColorTransferFunction`` / ``vtkPiecewiseFunction`` (piecewise linear and
    clamped, as our look-up is), linear interpolation, no shading, and our opacity
    unit distance (default the smallest spacing)."""
    color = vtk.vtkColorTransferFunction()
    opacity = vtk.vtkPiecewiseFunction()
    lo, hi = tf.value_range
    for x, (r, g, b, a) in zip(np.linspace(lo, hi, tf.table_size), tf.table):
        color.AddRGBPoint(float(x), float(r), float(g), float(b))
        opacity.AddPoint(float(x), float(a))
    prop = vtk.vtkVolumeProperty()
    prop.SetColor(color)
    prop.SetScalarOpacity(opacity)
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOff()
    unit = tf.unit_distance if tf.unit_distance is not None else float(volume.spacing.min())
    prop.SetScalarOpacityUnitDistance(unit)
    return prop


def set_camera(renderer, camera: Camera) -> None:
    """Point ``renderer``'s active camera as ``camera``: eye, target, up, vertical
    field of view (or parallel scale), clipping range around the scene."""
    cam = renderer.GetActiveCamera()
    cam.SetPosition(*camera.eye)
    cam.SetFocalPoint(*camera.target)
    cam.SetViewUp(*camera.basis()[2])
    if camera.projection == "perspective":
        cam.ParallelProjectionOff()
        cam.SetViewAngle(camera.fov_y)
    else:
        cam.ParallelProjectionOn()
        cam.SetParallelScale(camera.ortho_height / 2.0)
    renderer.ResetCameraClippingRange()


def read_rgba(vtk, ns, window, width: int, height: int) -> np.ndarray:
    """The window's pixels as float32 (H, W, 4), row 0 at the top, alpha 1 (composited
    over the black background)."""
    buf = vtk.vtkUnsignedCharArray()
    window.GetRGBACharPixelData(0, 0, width - 1, height - 1, 0, buf)
    rgba = ns.vtk_to_numpy(buf).reshape(height, width, 4)[::-1].astype(np.float32) / 255.0
    rgba[..., 3] = 1.0
    return rgba


class Scene:
    """A VTK render window holding ``volume`` classified by ``tf``, ready to render."""

    def __init__(self, volume: Volume, tf: TransferFunction, dt: float) -> None:
        import numba

        vtk, ns = load_vtk()
        self._vtk = vtk
        self._ns = ns
        nx, ny, nz = volume.dims
        image = vtk.vtkImageData()
        image.SetDimensions(nx, ny, nz)
        image.SetSpacing(*(float(s) for s in volume.spacing))
        image.SetOrigin(*(float(o) for o in volume.origin))
        self._flat = np.ascontiguousarray(volume.data).ravel()  # kept alive: VTK shares it
        scalars = ns.numpy_to_vtk(self._flat, deep=False)
        scalars.SetName("values")
        image.GetPointData().SetScalars(scalars)

        prop = volume_property(vtk, volume, tf)

        mapper = vtk.vtkFixedPointVolumeRayCastMapper()
        mapper.SetInputData(image)
        mapper.AutoAdjustSampleDistancesOff()
        mapper.LockSampleDistanceToInputSpacingOff()
        mapper.SetSampleDistance(float(dt))
        mapper.SetInteractiveSampleDistance(float(dt))
        mapper.SetImageSampleDistance(1.0)
        mapper.SetNumberOfThreads(numba.get_num_threads())

        actor = vtk.vtkVolume()
        actor.SetMapper(mapper)
        actor.SetProperty(prop)
        self._renderer = vtk.vtkRenderer()
        self._renderer.SetBackground(0.0, 0.0, 0.0)
        self._renderer.AddVolume(actor)
        self._window = vtk.vtkRenderWindow()
        self._window.SetOffScreenRendering(1)
        self._window.AddRenderer(self._renderer)
        # keep references: VTK objects die with their last Python reference
        self._keep = (image, scalars, prop, mapper, actor)

    def render(self, camera: Camera, width: int, height: int) -> tuple[np.ndarray, float]:
        """One frame: ``(rgba, ms)``, rgba float32 (H, W, 4) premultiplied over black."""
        self._window.SetSize(int(width), int(height))
        set_camera(self._renderer, camera)
        t0 = time.perf_counter()
        self._window.Render()
        ms = (time.perf_counter() - t0) * 1e3
        rgba = read_rgba(self._vtk, self._ns, self._window, width, height)
        return rgba, ms


def render(volume: Volume, tf: TransferFunction, camera: Camera, width: int, height: int,
           dt: float) -> tuple[np.ndarray, float]:
    """Render one frame with VTK: ``(rgba, ms)`` (see :class:`Scene`)."""
    return Scene(volume, tf, dt).render(camera, width, height)
