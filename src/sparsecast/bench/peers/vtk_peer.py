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

__all__ = ["NAME", "unavailable_reason", "Scene", "render"]

NAME = "vtk"


def unavailable_reason() -> str | None:
    """None when VTK can render offscreen here, otherwise why not."""
    try:
        _vtk()
    except ImportError as exc:
        return f"vtk is not installed ({exc}); pip install 'sparsecast[peers]'"
    return None


def _vtk():
    # Headless machines have no X server: ask for EGL (or OSMesa) before VTK picks.
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import vtkmodules.all as vtk  # noqa: F401  (loads every rendering backend)
    from vtkmodules.util import numpy_support

    vtk.vtkObject.GlobalWarningDisplayOff()
    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_ERROR)
    return vtk, numpy_support


class Scene:
    """A VTK render window holding ``volume`` classified by ``tf``, ready to render."""

    def __init__(self, volume: Volume, tf: TransferFunction, dt: float) -> None:
        import numba

        vtk, ns = _vtk()
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
        self._keep = (image, scalars, color, opacity, prop, mapper, actor)

    def render(self, camera: Camera, width: int, height: int) -> tuple[np.ndarray, float]:
        """One frame: ``(rgba, ms)``, rgba float32 (H, W, 4) premultiplied over black."""
        self._window.SetSize(int(width), int(height))
        cam = self._renderer.GetActiveCamera()
        cam.SetPosition(*camera.eye)
        cam.SetFocalPoint(*camera.target)
        cam.SetViewUp(*camera.basis()[2])
        if camera.projection == "perspective":
            cam.ParallelProjectionOff()
            cam.SetViewAngle(camera.fov_y)
        else:
            cam.ParallelProjectionOn()
            cam.SetParallelScale(camera.ortho_height / 2.0)
        self._renderer.ResetCameraClippingRange()
        t0 = time.perf_counter()
        self._window.Render()
        ms = (time.perf_counter() - t0) * 1e3
        buf = self._vtk.vtkUnsignedCharArray()
        self._window.GetRGBACharPixelData(0, 0, width - 1, height - 1, 0, buf)
        rgba = self._ns.vtk_to_numpy(buf).reshape(height, width, 4)[::-1].astype(np.float32) / 255.0
        rgba[..., 3] = 1.0  # composited over the black background
        return rgba, ms


def render(volume: Volume, tf: TransferFunction, camera: Camera, width: int, height: int,
           dt: float) -> tuple[np.ndarray, float]:
    """Render one frame with VTK: ``(rgba, ms)`` (see :class:`Scene`)."""
    return Scene(volume, tf, dt).render(camera, width, height)
