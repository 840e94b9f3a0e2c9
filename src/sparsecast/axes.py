"""Named directions of the world frame: the ``up`` axis of a scene, and the anatomical
orientation of a volume with its named views.

Two ideas share one representation, an **orbit frame**: a rotation ``M`` (3x3, columns
``right``, ``forward``, ``up``, det +1) from the canonical frame of
:meth:`sparsecast.Camera.orbit` (+z up, azimuth 0 looking along +y, +x to the right)
to world coordinates. The orbit's angles are taken in that frame, so

* ``up="y"`` makes world +y screen-up (azimuth turns about +y), and
* a named view (``"anterior"``) is the frame whose azimuth 0, elevation 0 camera looks
  at the patient from that side.

Rotating the camera, never the data, keeps every volume index exact.

**Anatomical orientation** is kept as axis codes: one letter of ``L R A P S I`` per
voxel axis naming where ``+i``, ``+j``, ``+k`` point in the patient (``("R", "A", "S")``
for RAS+ data; nibabel's ``aff2axcodes`` convention). A :class:`~sparsecast.Volume`'s
world axes are its index axes (``world = origin + spacing * index``, spacing > 0), so
world +x points where ``+i`` does.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .errors import ParameterError

__all__ = [
    "UP_AXES", "VIEWS", "Orientation", "axis_vector", "up_frame", "up_rotation",
    "check_orientation", "anatomical_direction", "view_frame", "axcodes", "space_directions", "is_mirrored",
]

#: the names ``up`` accepts
UP_AXES = ("x", "y", "z", "-x", "-y", "-z")

#: axis codes of one voxel axis each, for (+i, +j, +k)
Orientation = tuple[str, str, str]

_OPPOSITE = {"L": "R", "R": "L", "A": "P", "P": "A", "S": "I", "I": "S"}

#: view name -> (the side the camera looks from, the patient direction that is screen-up):
#: superior up for the four side views, anterior up looking from the top or the bottom
VIEWS: dict[str, tuple[str, str]] = {
    "anterior": ("A", "S"), "posterior": ("P", "S"), "left": ("L", "S"), "right": ("R", "S"),
    "superior": ("S", "A"), "inferior": ("I", "A"),
}


def axis_vector(name: str, what: str = "up") -> np.ndarray:
    """The unit world vector of an axis name (``"x"``, ``"-y"``, ``"+z"``, ...).

    Returns
    -------
    (3,) ndarray of float64
    """
    key = str(name).strip().lower().removeprefix("+") if isinstance(name, str) else None
    if key not in UP_AXES:
        raise ParameterError(f"{what}: expected one of {', '.join(UP_AXES)}, got {name!r}")
    v = np.zeros(3)
    v["xyz".index(key[-1])] = -1.0 if key.startswith("-") else 1.0
    return v


def _frame(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Columns ``(forward x up, forward, up)``: right-handed (det +1) for unit ``forward ⟂ up``,
    and the right vector is the one :meth:`Camera.basis` computes."""
    return np.stack([np.cross(forward, up), forward, up], axis=1)


def up_frame(up: str) -> np.ndarray:
    """The orbit frame with world axis ``up`` on top.

    At azimuth 0 the camera looks along ``up x right``, where ``right`` is +x (+y when
    ``up`` is ±x): for ``up="y"`` that is -z, so a y-up mesh (OpenGL convention, front
    towards +z) is seen from the front; ``up="-y"`` looks along +z (the OpenCV camera).
    ``up="z"`` is the identity.

    Returns
    -------
    (3, 3) ndarray of float64
        Columns ``right``, ``forward``, ``up`` in world coordinates; a rotation.
    """
    u = axis_vector(up, "up")
    right = np.array([0.0, 1.0, 0.0]) if u[0] else np.array([1.0, 0.0, 0.0])
    return _frame(np.cross(u, right), u)


def up_rotation(up: str) -> np.ndarray:
    """The rotation (3x3, det +1) that turns world axis ``up`` into +z: ``up_frame(up).T``.

    Apply it to points and normals alike (``p @ R.T``) to make a ``up``-up scene z-up.
    """
    return up_frame(up).T


def check_orientation(codes: str | Sequence[str] | None, what: str = "orientation") -> Orientation | None:
    """Axis codes from ``"RAS"``, ``"lps"`` or ``("L", "P", "S")``; None stays None.

    Raises
    ------
    ParameterError
        Not three letters of ``L R A P S I`` with one letter of each pair.
    """
    if codes is None:
        return None
    letters = tuple(str(c).upper() for c in codes) if not isinstance(codes, str) else tuple(codes.strip().upper())
    pairs = sorted(min(c, _OPPOSITE.get(c, c)) for c in letters)
    if len(letters) != 3 or any(c not in _OPPOSITE for c in letters) or pairs != ["A", "I", "L"]:
        raise ParameterError(
            f"{what}: expected three axis codes, one of L/R, one of A/P and one of S/I, for +i, +j, +k "
            f"(e.g. RAS or LPS), got {codes!r}"
        )
    return letters  # type: ignore[return-value]


def anatomical_direction(orientation: Orientation, letter: str) -> np.ndarray:
    """The unit world vector pointing towards ``letter`` (``"A"``: anterior) for a volume of
    ``orientation`` (whose world axes are its voxel axes)."""
    v = np.zeros(3)
    for axis, code in enumerate(orientation):
        if code == letter:
            v[axis] = 1.0
        elif code == _OPPOSITE[letter]:
            v[axis] = -1.0
    return v


def is_mirrored(orientation: Orientation | None) -> bool:
    """Whether the codes are left-handed (LAS, RPS, ...): the world, built from the voxel
    axes, is then the patient's mirror image, which a camera shows right only mirrored."""
    return orientation is not None and bool(np.linalg.det(space_directions(orientation)) < 0)


def view_frame(orientation: Orientation | None, view: str, source: str = "volume") -> np.ndarray:
    """The orbit frame whose azimuth 0, elevation 0 camera shows the patient from ``view``.

    The camera sits on the ``view`` side looking back at the centre, with superior on top
    (anterior on top for ``superior`` / ``inferior``); e.g. ``anterior`` faces the patient,
    whose left is then on the screen's right (the radiological convention).

    Parameters
    ----------
    orientation : axis codes or None
        The volume's :attr:`~sparsecast.Volume.orientation`.
    view : str
        One of :data:`VIEWS`.
    source : str
        Name of the volume in the error message.

    Returns
    -------
    (3, 3) ndarray of float64
        Columns ``right``, ``forward``, ``up``: a rotation, or for left-handed codes
        (:func:`is_mirrored`: the world is the patient's mirror image) a reflection whose
        ``right`` is still the patient's side on screen right; the camera then mirrors
        its image (``Camera.mirror``).

    Raises
    ------
    ParameterError
        Unknown view, or a volume without orientation.
    """
    if not isinstance(view, str) or view.lower() not in VIEWS:
        raise ParameterError(f"view: expected one of {', '.join(VIEWS)}, got {view!r}")
    if orientation is None:
        raise ParameterError(
            f"view {view!r}: {source} has no anatomical orientation (an NRRD 'space' such as "
            f"left-posterior-superior, or a NIfTI sform/qform); named views need one: pass "
            f"orientation= / --orientation with the axis codes of +i, +j, +k (e.g. RAS or LPS), "
            f"or use azimuth / elevation / up"
        )
    side, top = VIEWS[view.lower()]
    m = _frame(-anatomical_direction(orientation, side), anatomical_direction(orientation, top))
    if is_mirrored(orientation):
        m[:, 0] *= -1.0  # the patient's screen-right, so that azimuth turns the same anatomical way
    return m


def axcodes(directions: np.ndarray, space: Orientation = ("R", "A", "S")) -> Orientation | None:
    """Axis codes of voxel axes whose world directions are the *columns* of ``directions``
    (3x3), given in a space whose +x, +y, +z point towards ``space`` (RAS for NIfTI, e.g.
    LPS for an NRRD ``left-posterior-superior``); oblique axes get their nearest code
    (nibabel's ``io_orientation``). None when the directions are singular."""
    from nibabel.orientations import aff2axcodes

    d = np.asarray(directions, dtype=np.float64)
    if d.shape != (3, 3) or not np.all(np.isfinite(d)) or abs(np.linalg.det(d)) < 1e-12 * max(np.abs(d).max(), 1e-300) ** 3:
        return None
    aff = np.eye(4)
    aff[:3, :3] = d
    labels = tuple((_OPPOSITE[c], c) for c in space)  # (towards -axis, towards +axis)
    codes = aff2axcodes(aff, labels=labels)
    return check_orientation(codes) if None not in codes else None


def space_directions(orientation: Orientation, space: Orientation = ("R", "A", "S")) -> np.ndarray:
    """The inverse of :func:`axcodes` for axis-aligned data: 3x3 whose column ``a`` is the
    unit vector towards ``orientation[a]`` in ``space`` (a signed permutation; with the
    default RAS, the direction cosines of a NIfTI affine)."""
    return np.stack([anatomical_direction(space, c) for c in orientation], axis=1)
