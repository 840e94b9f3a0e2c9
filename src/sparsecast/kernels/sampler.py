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
"""

from __future__ import annotations

from typing import NamedTuple

from numba import njit
from numba.extending import overload

from .bricked import bricked_gradient, bricked_nearest, bricked_trilinear
from .layout import layout_of
from .sample import gradient, trilinear

__all__ = ["Trilinear", "Nearest", "SAMPLERS", "sampler_for", "sample", "sample_gradient", "nearest"]


class Trilinear(NamedTuple):
    """Sampler marker: trilinear interpolation of the eight voxels around a point (the default)."""

    tag: int = 0


class Nearest(NamedTuple):
    """Sampler marker: the value of the voxel nearest to a point (label volumes)."""

    tag: int = 0


#: sampler names (``TransferFunction.sampling``) and their markers
SAMPLERS = {"trilinear": Trilinear, "nearest": Nearest}


def sampler_for(name: str) -> Trilinear | Nearest:
    """The marker for a sampler name (``"trilinear"`` or ``"nearest"``)."""
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

