"""Cameras: orthographic and perspective, look-at, orbit and fit-to-volume.

A :class:`Camera` is a plain description (eye, target, up, projection, field of
view); :meth:`Camera.ray_params` packs it into the flat float64 array that the
Numba ray generator (:func:`sparsecast.kernels.camera.primary_ray`) reads.

Orbit convention: +z is up on screen. At azimuth 0 and elevation 0 the camera looks
along +y, so +x points right; azimuth moves the camera clockwise about +z seen from
above (azimuth 90 looks along +x from the -x side, so the object seems to turn
counter-clockwise) and elevation raises it towards +z. ``up=`` and ``view=`` rotate
that frame (:mod:`sparsecast.axes`): the angles are then taken about another world axis,
or from a named anatomical view. The camera moves, the data never does, so every index
stays exact.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from .axes import is_mirrored, up_frame, view_frame
from .errors import ParameterError

__all__ = ["Camera", "Projection"]

Projection = Literal["orthographic", "perspective"]
_PROJECTIONS = ("orthographic", "perspective")

#: layout of Camera.ray_params(); mirrored by kernels.camera
RAY_PARAMS_SIZE = 13


def _unit(v: np.ndarray, name: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not np.isfinite(n) or n == 0.0:
        raise ParameterError(f"{name}: expected a non-zero finite vector, got {np.asarray(v).tolist()}")
    return v / n


def _vec3(v, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ParameterError(f"{name}: expected 3 finite numbers (x, y, z), got {v!r}")
    return a


@dataclass(frozen=True)
class Camera:
    """A pinhole (perspective) or parallel (orthographic) camera in world space.

    Parameters
    ----------
    eye : (3,) array_like
        Camera position.
    target : (3,) array_like
        Point looked at; must differ from ``eye``.
    up : (3,) array_like
        Approximate up direction; made orthogonal to the view direction.
    projection : {"orthographic", "perspective"}
    fov_y : float
        Perspective only: vertical field of view in degrees, in (0, 180).
    ortho_height : float
        Orthographic only: world-space height of the view.
    mirror : bool
        Flip the image left-right (screen right is ``up x forward``, not ``forward x up``):
        how a left-handed world looks right. Voxel axes whose anatomical codes are
        left-handed (LAS, a flipped NRRD axis) make the world a mirror image of the patient,
        and no rotation undoes that; named views set it (:meth:`orbit`).
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    projection: Projection = "perspective"
    fov_y: float = 30.0
    ortho_height: float = 1.0
    mirror: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "eye", _vec3(self.eye, "eye"))
        object.__setattr__(self, "target", _vec3(self.target, "target"))
        object.__setattr__(self, "up", _vec3(self.up, "up"))
        if self.projection not in _PROJECTIONS:
            raise ParameterError(f"projection: expected one of {_PROJECTIONS}, got {self.projection!r}")
        if not (0.0 < self.fov_y < 180.0):
            raise ParameterError(f"fov_y: expected degrees in (0, 180), got {self.fov_y}")
        if not (np.isfinite(self.ortho_height) and self.ortho_height > 0):
            raise ParameterError(f"ortho_height: expected a positive number, got {self.ortho_height}")
        forward = _unit(self.target - self.eye, "target - eye")
        if abs(float(np.dot(forward, _unit(self.up, "up")))) > 1.0 - 1e-9:
            raise ParameterError("up: must not be parallel to the view direction (target - eye)")

    # -- constructors -----------------------------------------------------
    @classmethod
    def look_at(
        cls,
        eye,
        target,
        up=(0.0, 0.0, 1.0),
        *,
        projection: Projection = "perspective",
        fov_y: float = 30.0,
        ortho_height: float = 1.0,
        mirror: bool = False,
    ) -> "Camera":
        """A camera at ``eye`` looking at ``target``."""
        return cls(eye, target, up, projection, fov_y, ortho_height, bool(mirror))

    @classmethod
    def orbit(
        cls,
        volume,
        azimuth: float = 0.0,
        elevation: float = 0.0,
        *,
        projection: Projection = "perspective",
        fov_y: float = 30.0,
        zoom: float = 1.0,
        distance: float | None = None,
        pan: tuple[float, float] = (0.0, 0.0),
        up: str | None = None,
        view: str | None = None,
    ) -> "Camera":
        """A camera on a sphere around ``volume`` that frames it (fit-to-volume).

        Parameters
        ----------
        volume : Volume
            The volume to frame; any object with ``center`` and ``diagonal`` works
            (and ``orientation`` for ``view``).
        azimuth, elevation : float
            Angles in degrees (see the module docstring for the convention), in the
            frame that ``up`` or ``view`` sets.
        projection : {"orthographic", "perspective"}
        fov_y : float
            Perspective vertical field of view in degrees.
        zoom : float
            > 1 magnifies, < 1 shows more surroundings.
        distance : float, optional
            Eye-to-centre distance; default fits the volume's bounding sphere.
        pan : (float, float)
            Shift of the view (eye and target together) to the right and up, in
            units of the bounding-sphere radius.
        up : {"x", "y", "z", "-x", "-y", "-z"}, optional
            World axis that is screen-up at elevation 0; azimuth turns about it
            (default ``"z"``; :func:`sparsecast.axes.up_frame` says where azimuth 0 looks).
        view : {"anterior", "posterior", "left", "right", "superior", "inferior"}, optional
            Look at the patient from that side, superior up (anterior up for superior /
            inferior); ``azimuth`` / ``elevation`` then orbit away from it. Needs
            ``volume.orientation`` (axis codes); excludes ``up``. A left-handed
            orientation (LAS) gives a ``mirror`` camera, so the patient's left is where it
            belongs (on screen right seen from the front).

        Raises
        ------
        ParameterError
            Bad angles, zoom, distance, pan, ``up`` or ``view``; ``up`` and ``view``
            both given; ``view`` for a volume without orientation (naming it).
        """
        if not (np.isfinite(zoom) and zoom > 0):
            raise ParameterError(f"zoom: expected a positive number, got {zoom}")
        for nm, ang in (("azimuth", azimuth), ("elevation", elevation)):
            if not np.isfinite(ang):
                raise ParameterError(f"{nm}: expected a finite angle in degrees, got {ang}")
        mirror = False
        if view is not None:
            if up is not None:
                raise ParameterError(f"up: a view ({view!r}) sets the up direction itself; give up or view, not both")
            orientation = getattr(volume, "orientation", None)
            label = getattr(volume, "name", None) or getattr(volume, "source", None) or type(volume).__name__
            frame = view_frame(orientation, view, repr(label))
            mirror = is_mirrored(orientation)
        else:
            frame = up_frame("z" if up is None else up)
        center = np.asarray(volume.center, dtype=np.float64)
        radius = max(0.5 * float(volume.diagonal), 1e-6)
        az, el = np.radians(azimuth), np.radians(elevation)
        # Direction from the centre to the eye, in the orbit frame (+z up), then in the world.
        to_eye = frame @ np.array([-np.sin(az) * np.cos(el), -np.cos(az) * np.cos(el), np.sin(el)])
        # Screen-up is d(to_eye)/d(elevation): orthogonal to the view direction for
        # every angle, the frame's up at the horizon and continuous through the poles.
        up = frame @ np.array([np.sin(az) * np.sin(el), np.cos(az) * np.sin(el), np.cos(el)])
        if distance is None:
            if projection == "perspective":
                distance = radius / np.sin(np.radians(fov_y) / 2.0) / zoom
            else:
                distance = 2.0 * radius  # any eye outside the bounding sphere works
        if not (np.isfinite(distance) and distance > 0):
            raise ParameterError(f"distance: expected a positive number, got {distance}")
        pan_arr = np.asarray(pan, dtype=np.float64)
        if pan_arr.shape != (2,) or not np.all(np.isfinite(pan_arr)):
            raise ParameterError(f"pan: expected two finite numbers (right, up), got {pan!r}")
        right = np.cross(-to_eye, up) * (-1.0 if mirror else 1.0)  # screen right
        right /= np.linalg.norm(right)
        target = center + radius * (pan_arr[0] * right + pan_arr[1] * up)
        eye = target + distance * to_eye
        return cls(eye, target, up, projection, fov_y, ortho_height=2.0 * radius / zoom, mirror=mirror)

    # -- derived frame ----------------------------------------------------
    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Orthonormal ``(forward, right, up)`` vectors; ``right`` is the screen's right
        (``up x forward`` for a ``mirror`` camera, a left-handed basis)."""
        forward = _unit(self.target - self.eye, "target - eye")
        right = _unit(np.cross(forward, self.up), "forward x up")
        up = np.cross(right, forward)
        return forward, (-right if self.mirror else right), up

    def ray_params(self, width: int, height: int) -> np.ndarray:
        """Flat float64 array read by :func:`kernels.camera.primary_ray`.

        Layout: ``eye[3], forward[3], R[3], U[3], is_perspective``. A pixel at
        normalised screen coordinates ``(u, v)`` in ``[-1, 1]`` gets the ray
        ``origin = eye + u R + v U, dir = forward`` (orthographic) or
        ``origin = eye, dir = normalize(forward + u R + v U)`` (perspective).
        """
        forward, right, up = self.basis()
        aspect = width / height
        if self.projection == "perspective":
            half = np.tan(np.radians(self.fov_y) / 2.0)
        else:
            half = self.ortho_height / 2.0
        p = np.empty(RAY_PARAMS_SIZE, np.float64)
        p[0:3] = self.eye
        p[3:6] = forward
        p[6:9] = right * half * aspect
        p[9:12] = up * half
        p[12] = 1.0 if self.projection == "perspective" else 0.0
        return p

    def rays(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """All primary rays as NumPy arrays ``(origins, directions)`` of shape (H, W, 3).

        The vectorised twin of the Numba generator, for tests and small tools.
        """
        p = self.ray_params(width, height)
        u = (np.arange(width) + 0.5) / width * 2.0 - 1.0
        v = 1.0 - (np.arange(height) + 0.5) / height * 2.0
        uu, vv = np.meshgrid(u, v)
        offs = uu[..., None] * p[6:9] + vv[..., None] * p[9:12]
        if p[12]:
            d = p[3:6] + offs
            d /= np.linalg.norm(d, axis=-1, keepdims=True)
            o = np.broadcast_to(p[0:3], d.shape).copy()
        else:
            o = p[0:3] + offs
            d = np.broadcast_to(p[3:6], o.shape).copy()
        return o, d
