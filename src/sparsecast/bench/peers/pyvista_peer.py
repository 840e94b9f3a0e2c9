"""VTK's GPU ray caster through pyvista (``Plotter.add_volume(mapper="gpu")``), off screen.

What a pyvista user on a headless machine gets: no X server, so VTK opens an EGL
(or OSMesa) context, which on a machine without a GPU is Mesa's llvmpipe, a
software OpenGL that runs the fragment shaders on the CPU cores. The record says
which OpenGL renderer ran (``gl_renderer``).

Mapping of a sparsecast case onto pyvista / VTK, as for :mod:`.vtk_peer`:

- volume: a ``pyvista.ImageData`` with dimensions ``(nx, ny, nz)``, our spacing
  and origin, the C-ordered ``(nz, ny, nx)`` array raveled (VTK's x-fastest order);
- TF: ``add_volume`` makes the actor, then its property gets the colour and opacity
  functions of :func:`.vtk_peer.volume_property` (one point per entry of our baked
  table, linear interpolation, no shading, our opacity unit distance);
- step: the mapper's sample distance is our ``dt``, automatic adjustment off;
- camera: eye, target, up and field of view (or parallel scale) as ours;
- threads: llvmpipe's ``LP_NUM_THREADS`` is set to Numba's thread count unless the
  environment sets it, so both use the same cores.

The GPU works asynchronously from the caller, so a frame's time is the render call
plus the read-back of its pixels (the read-back waits for the frame to finish).
"""

from __future__ import annotations

import os
import time
from functools import lru_cache

import numpy as np

from ...camera import Camera
from ...transfer import TransferFunction
from ...volume import Volume
from .vtk_peer import load_vtk, read_rgba, set_camera, volume_property

__all__ = ["NAME", "unavailable_reason", "Scene", "render"]

NAME = "pyvista"


def _prepare_environment() -> None:
    import numba

    # Before the first OpenGL context: Mesa reads it when it starts its threads.
    os.environ.setdefault("LP_NUM_THREADS", str(numba.get_num_threads()))


def unavailable_reason() -> str | None:
    """None when pyvista can open an off-screen OpenGL context here, otherwise why not."""
    try:
        import pyvista  # noqa: F401
    except ImportError as exc:
        return f"pyvista is not installed ({exc}); pip install 'sparsecast[peers]'"
    return _context_failure()


@lru_cache(maxsize=1)
def _context_failure() -> str | None:
    """Render one 8x8 frame off screen; the reason it failed, or None (tried once per process)."""
    try:
        _prepare_environment()
        load_vtk()  # picks EGL on a headless machine before pyvista makes a window
        import pyvista as pv

        plotter = pv.Plotter(off_screen=True, window_size=(8, 8))
        try:
            plotter.ren_win.Render()  # the window itself: pyvista's render() waits for show()
            if not plotter.ren_win.SupportsOpenGL():
                return "pyvista: no OpenGL context (neither X, EGL nor OSMesa started)"
        finally:
            plotter.close()
    except Exception as exc:  # any failure to start is the reason, not a crash
        return f"pyvista cannot render off screen: {type(exc).__name__}: {exc}"
    return None


def _gl_renderer(window) -> str | None:
    """The ``OpenGL renderer string`` VTK reports (e.g. ``llvmpipe (LLVM 15.0.6, 256 bits)``)."""
    for line in window.ReportCapabilities().splitlines():  # only after the first Render()
        if line.startswith("OpenGL renderer string:"):
            return line.split(":", 1)[1].strip()
    return None


class Scene:
    """A pyvista plotter holding ``volume`` classified by ``tf`` on the GPU mapper."""

    def __init__(self, volume: Volume, tf: TransferFunction, dt: float) -> None:
        _prepare_environment()
        vtk, ns = load_vtk()
        import pyvista as pv

        self._vtk, self._ns = vtk, ns
        grid = pv.ImageData(dimensions=tuple(int(n) for n in volume.dims),
                            spacing=tuple(float(s) for s in volume.spacing),
                            origin=tuple(float(o) for o in volume.origin))
        grid.point_data["values"] = np.ascontiguousarray(volume.data).ravel()
        self._plotter = pv.Plotter(off_screen=True, window_size=(64, 64))
        self._plotter.set_background("black")
        lo, hi = tf.value_range
        actor = self._plotter.add_volume(grid, scalars="values", mapper="gpu", clim=(float(lo), float(hi)),
                                         shade=False, blending="composite", show_scalar_bar=False)
        self._prop = volume_property(vtk, volume, tf)  # our table, not a colormap's
        actor.SetProperty(self._prop)
        mapper = actor.GetMapper()
        mapper.AutoAdjustSampleDistancesOff()
        mapper.LockSampleDistanceToInputSpacingOff()
        mapper.SetSampleDistance(float(dt))
        self._keep = (grid, actor)
        self.info: dict[str, object] = {}

    def render(self, camera: Camera, width: int, height: int) -> tuple[np.ndarray, float]:
        """One frame: ``(rgba, ms)``, rgba float32 (H, W, 4) premultiplied over black;
        ``ms`` includes the pixel read-back (where the asynchronous GPU frame ends)."""
        plotter = self._plotter
        window = plotter.ren_win
        window.SetSize(int(width), int(height))
        set_camera(plotter.renderer, camera)
        plotter.camera_set = True  # pyvista must not reset our camera on render
        t0 = time.perf_counter()
        window.Render()
        rgba = read_rgba(self._vtk, self._ns, window, width, height)
        ms = (time.perf_counter() - t0) * 1e3
        if not self.info:
            self.info = {"gl_renderer": _gl_renderer(window), "gl_window": window.GetClassName()}
        return rgba, ms

    def close(self) -> None:
        """Release the OpenGL context."""
        self._plotter.close()


def render(volume: Volume, tf: TransferFunction, camera: Camera, width: int, height: int,
           dt: float) -> tuple[np.ndarray, float]:
    """Render one frame with pyvista's GPU mapper: ``(rgba, ms)`` (see :class:`Scene`)."""
    scene = Scene(volume, tf, dt)
    try:
        return scene.render(camera, width, height)
    finally:
        scene.close()
