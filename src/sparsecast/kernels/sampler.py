"""How a lattice sample reads the voxels: trilinear interpolation or the nearest voxel.

The DVR driver takes the sampler as a *marker record* in its frame
(:class:`Trilinear` or :class:`Nearest`) and every marcher calls
:func:`sample` with it. The choice is made on the marker's Numba type, at
compile time, so each sampler gets its own specialisation of the marching loop
and pays no per-sample branch; ``cache=True`` keeps working (the markers are
this package's classes).

Nearest sampling is what label volumes (segmentations) need: a label id is a
name, not a quantity, and blending ids 2 and 4 would invent a label 3. Its
footprint is that of trilinear interpolation (the voxel a point rounds to is
one of the corners of its cell), so every brick statistic and empty-space
index built for trilinear sampling is conservative for nearest sampling too.

Smooth label boundaries (:class:`SmoothLabels`) interpolate per-label masks
instead: at a point, each label's weight is the sum of the trilinear weights of
the corners of its cell that hold it, and the sample's RGBA is the
weight-blended label colours, premultiplied (pre-classified interpolation, as
segmentation viewers do it). Ids are never blended into other ids, yet a
boundary is a smooth surface, not a staircase of voxels. Its footprint is the
same eight corners, so the same brick statistics and label sets stay
conservative.

Classification is part of the sampler. A marcher asks :func:`sample_alpha` for
a sample's opacity (and a token) and, only where that is non-zero,
:func:`sample_color` for its straight colour: for the value samplers that is
:func:`~.shade.tf_alpha` / :func:`~.shade.tf_color` of the sampled value, for
smooth labels the blend of the corners' table entries. Shading normals come
from :func:`sample_normal`: the field's gradient, or for smooth labels the
gradient of the blended opacity (a label's surface, not the id field's).
"""

from __future__ import annotations

from typing import NamedTuple

from numba import njit
from numba.extending import overload

from .borrow import NO_REFCOUNT
from .bricked import bricked_corners, bricked_gradient, bricked_nearest, bricked_trilinear
from .layout import layout_of
from .sample import clamp_point, corners, gradient, trilinear
from .shade import tf_alpha, tf_color

__all__ = ["Trilinear", "Nearest", "SmoothLabels", "SAMPLERS", "sampler_for", "sample", "sample_gradient",
           "cell_corners", "sample_alpha", "sample_color", "sample_normal", "nearest", "label_mix"]


class Trilinear(NamedTuple):
    """Sampler marker: trilinear interpolation of the eight voxels around a point (the default)."""

    tag: int = 0


class Nearest(NamedTuple):
    """Sampler marker: the value of the voxel nearest to a point (label volumes)."""

    tag: int = 0


class SmoothLabels(NamedTuple):
    """Sampler marker: per-label masks interpolated trilinearly (smooth label boundaries)."""

    tag: int = 0


#: sampler names (``TransferFunction.sampling``) and their markers
SAMPLERS = {"trilinear": Trilinear, "nearest": Nearest, "smooth-labels": SmoothLabels}


def sampler_for(name: str) -> Trilinear | Nearest | SmoothLabels:
    """The marker for a sampler name (``"trilinear"``, ``"nearest"`` or ``"smooth-labels"``)."""
    return SAMPLERS[name]()


@njit(cache=True, inline="always")
def nearest(flat, nx, ny, nz, x, y, z):
    """Value of the voxel nearest to index-space point ``(x, y, z)``.

    Ties (a coordinate exactly halfway between voxels) round up, i.e. the voxel
    is ``floor(x + 0.5)``; ``int`` truncates towards zero, which equals the floor
    wherever the clamp to ``[0, n-1]`` does not decide anyway.
    """
    i = min(max(int(x + 0.5), 0), nx - 1)
    j = min(max(int(y + 0.5), 0), ny - 1)
    k = min(max(int(z + 0.5), 0), nz - 1)
    return float(flat[(k * ny + j) * nx + i])


def sample(sampler, flat, nx, ny, nz, x, y, z):  # pragma: no cover - replaced by overloads in jitted code
    """The value at index-space point ``(x, y, z)`` as ``sampler`` reads it from ``flat``
    (a dense volume's 1-D view, or a :class:`~.bricked.BrickedVoxels`)."""
    raise NotImplementedError("sample is only callable from jitted code")


def sample_gradient(flat, nx, ny, nz, x, y, z):  # pragma: no cover - replaced by overloads in jitted code
    """Central-difference gradient of the trilinear field at ``(x, y, z)`` (either layout)."""
    raise NotImplementedError("sample_gradient is only callable from jitted code")


@overload(sample, inline="always")
def _sample(sampler, flat, nx, ny, nz, x, y, z):
    cls = getattr(sampler, "instance_class", None)
    layout = layout_of(flat)
    if cls is Trilinear and layout == "dense":
        return lambda sampler, flat, nx, ny, nz, x, y, z: trilinear(flat, nx, ny, nz, x, y, z)
    if cls is Nearest and layout == "dense":
        return lambda sampler, flat, nx, ny, nz, x, y, z: nearest(flat, nx, ny, nz, x, y, z)
    if cls is Trilinear and layout == "bricked":
        return lambda sampler, flat, nx, ny, nz, x, y, z: bricked_trilinear(flat, x, y, z)
    if cls is Nearest and layout == "bricked":
        return lambda sampler, flat, nx, ny, nz, x, y, z: bricked_nearest(flat, x, y, z)
    return None


@overload(sample_gradient, inline="always")
def _sample_gradient(flat, nx, ny, nz, x, y, z):
    layout = layout_of(flat)
    if layout == "dense":
        return lambda flat, nx, ny, nz, x, y, z: gradient(flat, nx, ny, nz, x, y, z)
    if layout == "bricked":
        return lambda flat, nx, ny, nz, x, y, z: bricked_gradient(flat, x, y, z)
    return None



@njit(cache=True, inline="always")
def _mix(table, v, v_lo, scale, w, a, r, g, b):
    """Add corner value ``v`` with trilinear weight ``w`` to the premultiplied blend."""
    i, f, al = tf_alpha(table, v, v_lo, scale)
    if al > 0.0:
        cr, cg, cb = tf_color(table, i, f)
        wa = w * al
        a += wa
        r += wa * cr
        g += wa * cg
        b += wa * cb
    return a, r, g, b


@njit(cache=True, inline="always")
def label_mix(table, v_lo, scale, v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz):
    """Opacity and premultiplied colour ``(a, r, g, b)`` of a cell's corner labels blended
    with the trilinear weights of ``(fx, fy, fz)``.

    Summing per corner is summing per label: a label's weight is the sum of the
    weights of the corners holding it, and each corner adds its label's (step
    corrected) table entry. Hidden labels add nothing, so they never tint a
    boundary; a corner's id is looked up as :func:`nearest` sampling would look it up.
    """
    gx = 1.0 - fx
    gy = 1.0 - fy
    gz = 1.0 - fz
    a = 0.0
    r = 0.0
    g = 0.0
    b = 0.0
    a, r, g, b = _mix(table, v000, v_lo, scale, gz * gy * gx, a, r, g, b)
    a, r, g, b = _mix(table, v001, v_lo, scale, gz * gy * fx, a, r, g, b)
    a, r, g, b = _mix(table, v010, v_lo, scale, gz * fy * gx, a, r, g, b)
    a, r, g, b = _mix(table, v011, v_lo, scale, gz * fy * fx, a, r, g, b)
    a, r, g, b = _mix(table, v100, v_lo, scale, fz * gy * gx, a, r, g, b)
    a, r, g, b = _mix(table, v101, v_lo, scale, fz * gy * fx, a, r, g, b)
    a, r, g, b = _mix(table, v110, v_lo, scale, fz * fy * gx, a, r, g, b)
    a, r, g, b = _mix(table, v111, v_lo, scale, fz * fy * fx, a, r, g, b)
    return a, r, g, b


def sample_alpha(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z):  # pragma: no cover - overloads
    """``(a, token)``: the step-corrected opacity at ``(x, y, z)`` and what
    :func:`sample_color` needs for its colour (a table position, or a blended colour)."""
    raise NotImplementedError("sample_alpha is only callable from jitted code")


def sample_color(sampler, table, token):  # pragma: no cover - replaced by overloads in jitted code
    """Straight colour ``(r, g, b)`` of a sample of non-zero opacity (see :func:`sample_alpha`)."""
    raise NotImplementedError("sample_color is only callable from jitted code")


def sample_normal(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z):  # pragma: no cover - overloads
    """Index-space shading normal (unnormalised) at ``(x, y, z)``: the field's gradient,
    or for :class:`SmoothLabels` the gradient of the blended opacity."""
    raise NotImplementedError("sample_normal is only callable from jitted code")


@overload(sample_alpha, inline="always")
def _sample_alpha(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z):
    cls = getattr(sampler, "instance_class", None)
    if cls is Trilinear or cls is Nearest:
        def by_value(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z):
            i, f, a = tf_alpha(table, sample(sampler, flat, nx, ny, nz, x, y, z), v_lo, scale)
            return a, (i, f)

        return by_value
    if cls is SmoothLabels:
        def smooth(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z):
            a, r, g, b = _smooth_rgba(flat, nx, ny, nz, table, v_lo, scale, x, y, z)
            return a, (r, g, b, a)

        return smooth
    return None


@overload(sample_color, inline="always")
def _sample_color(sampler, table, token):
    cls = getattr(sampler, "instance_class", None)
    if cls is Trilinear or cls is Nearest:
        return lambda sampler, table, token: tf_color(table, token[0], token[1])
    if cls is SmoothLabels:
        def straight(sampler, table, token):
            r, g, b, a = token
            return r / a, g / a, b / a  # a > 0: only samples of non-zero opacity get a colour

        return straight
    return None


@overload(sample_normal, inline="always")
def _sample_normal(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z):
    cls = getattr(sampler, "instance_class", None)
    if cls is Trilinear or cls is Nearest:
        return lambda sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z: sample_gradient(
            flat, nx, ny, nz, x, y, z)
    if cls is SmoothLabels:
        return lambda sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z: _smooth_alpha_gradient(
            flat, nx, ny, nz, table, v_lo, scale, x, y, z)
    return None


def cell_corners(flat, nx, ny, nz, x, y, z):  # pragma: no cover - replaced by overloads in jitted code
    """The eight corner values of the trilinear cell of ``(x, y, z)`` and its fractions,
    ``(v000, ..., v111, fx, fy, fz)`` as :func:`.sample.corners` returns them, from
    either layout (a dense volume's 1-D view or a bricked one): the same cell and the
    same values for the same point."""
    raise NotImplementedError("cell_corners is only callable from jitted code")


@overload(cell_corners, inline="always")
def _cell_corners_ol(flat, nx, ny, nz, x, y, z):
    layout = layout_of(flat)
    if layout == "dense":
        return lambda flat, nx, ny, nz, x, y, z: corners(flat, nx, ny, nz, x, y, z)
    if layout == "bricked":
        return lambda flat, nx, ny, nz, x, y, z: bricked_corners(flat, x, y, z)
    return None


# A plain call, not inlined: Numba's inline="always" works on its own IR and retypes
# the caller once per copy, and a smooth-label specialisation of the driver held
# several copies of this blend. Measured from a fresh cache, that specialisation
# compiled in about 100 s inlined and 10.5 s as a call; renders timed the same
# within noise, since one call per sample is small beside eight table lookups.
@njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _smooth_rgba(flat, nx, ny, nz, table, v_lo, scale, x, y, z):
    """:func:`label_mix` of the cell of ``(x, y, z)`` (either layout)."""
    v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz = cell_corners(flat, nx, ny, nz, x, y, z)
    return label_mix(table, v_lo, scale, v000, v001, v010, v011, v100, v101, v110, v111, fx, fy, fz)


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def _smooth_alpha(flat, nx, ny, nz, table, v_lo, scale, x, y, z):
    """The blended label opacity at ``(x, y, z)`` (:func:`_smooth_rgba`'s ``a``).

    Six calls make one gradient. Like :func:`_smooth_rgba` it stays a plain call:
    inlined, the six copies of the eight-corner blend took 25 s to compile, for
    one shaded path."""
    return _smooth_rgba(flat, nx, ny, nz, table, v_lo, scale, x, y, z)[0]


@njit(cache=True, **NO_REFCOUNT)
def _smooth_alpha_gradient(flat, nx, ny, nz, table, v_lo, scale, x, y, z):
    """Central differences (h = 1 voxel, clamped to the box) of the blended label opacity.

    Each neighbour is read from its own cell's brick: a brick that is not resident
    holds no visible label in its window, so its fill reads as opacity 0, as the
    real voxels would.
    """
    x0, y0, z0 = clamp_point(x - 1.0, y - 1.0, z - 1.0, nx, ny, nz)
    x1, y1, z1 = clamp_point(x + 1.0, y + 1.0, z + 1.0, nx, ny, nz)
    gx = 0.5 * (_smooth_alpha(flat, nx, ny, nz, table, v_lo, scale, x1, y, z)
                - _smooth_alpha(flat, nx, ny, nz, table, v_lo, scale, x0, y, z))
    gy = 0.5 * (_smooth_alpha(flat, nx, ny, nz, table, v_lo, scale, x, y1, z)
                - _smooth_alpha(flat, nx, ny, nz, table, v_lo, scale, x, y0, z))
    gz = 0.5 * (_smooth_alpha(flat, nx, ny, nz, table, v_lo, scale, x, y, z1)
                - _smooth_alpha(flat, nx, ny, nz, table, v_lo, scale, x, y, z0))
    return gx, gy, gz
