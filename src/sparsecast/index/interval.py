"""The interval-iterator protocol between spatial indices and the DVR driver.

Every index hands the driver (:mod:`sparsecast.render.driver`) one *record*: a
``typing.NamedTuple`` of arrays and scalars, one record class per index kind.
The driver never looks inside it; it calls four generic functions, which each
index package implements for its record class with ``numba.extending.overload``
(dispatch on the record's Numba type, so ``cache=True`` keeps working across
processes; a closure factory would recompile in every new process):

``make_scratch(record)``
    Per-tile scratch (a stack, a leaf box ...), allocated once per 8x8 tile.
``start_tile(record, scratch, corners, box, planes) -> bool``
    Begin an 8x8 tile (optional: records whose class sets ``TILE = True``), and
    say whether any ray of it may meet an interval: ``False`` promises that
    ``next_interval`` would yield nothing for every ray of the tile, and the
    driver then writes the tile's pixels without setting up its rays.
    ``corners`` holds the index-space rays ``(ox, oy, oz, dx, dy, dz)`` of the
    tile's four corner pixels, ``(x0, y0), (x1, y0), (x1, y1), (x0, y1)``
    (:func:`~sparsecast.kernels.camera.tile_corner_rays`); every ray of the tile
    lies in their convex hull (ray generation is affine in the pixel), so an index
    may cull its structure once for the tile's frustum and keep what is left in
    ``scratch`` (the deep k-d tree's leaf list). ``box`` is the frame's index-space
    clip box ``(x0, y0, z0, x1, y1, z1)`` and ``planes`` its ``(m, 4)`` clip
    half-spaces ``n . x >= c``: every sample the driver takes lies inside both (up to
    rounding), so what lies wholly outside them (by a tolerance) may be culled too.
``start_ray(record, scratch, ray, t_lo, t_hi) -> state``
    Begin a ray. ``ray`` is the index-space ``(ox, oy, oz, dx, dy, dz)``, the
    parameter ``t`` a world-space distance; ``[t_lo, t_hi]`` (``t_lo >= 0``) is
    the ray's interval in the clip box. ``state`` is a tuple of scalars.
``next_interval(record, scratch, ray, state, t_covered) -> (t0, t1, state)``
    The next interval of the ray that may hold samples of non-zero opacity,
    front to back (``t0`` non-decreasing); ``t0 > t1`` once there are no more.
    ``t_covered`` is the end of the segment the driver holds open (``-inf``
    when none): an interval ending there has nothing new, and an index may
    prune subtrees against it (the LBVH does). Intervals may overlap, touch
    or extend past ``[t_lo, t_hi]``; the driver merges touching ones and
    clamps lattice indices to the clip.
``integrate(record, scratch, state, mode, sampler, flat, nx, ny, nz, table, v_lo, scale, inv_spacing, dt, ert,``
``shading, ray, wdir, t0, t1, k_next, k_min, k_max, acc)``
    Composite one interval ``[t0, t1]`` onto the premultiplied ``acc = (r, g, b, a)``
    and return ``(r, g, b, a, k_next, n_samples, n_nonempty)``; ``wdir`` is the unit
    world direction (shading), ``[k_min, k_max]`` the lattice indices the clip
    admits, ``mode`` the frame's mode marker (:class:`~sparsecast.kernels.march.Dvr`,
    :class:`~sparsecast.kernels.iso.Iso`, :class:`~sparsecast.kernels.iso.IsoDvr`) and
    ``sampler`` its :mod:`sampler <sparsecast.kernels.sampler>` marker. Arguments are plain arrays, scalars and tuples of
    scalars (no records beyond the index's own: reading arrays out of records
    costs reference-count atomics per interval), at most 30 of them: more make
    CPython pass them as ``*args``, which Numba cannot inline. The default, for every record whose class does not
    set ``LATTICE = False``, is the exact lattice march
    (:func:`sparsecast.kernels.march.march_interval`, or
    :func:`sparsecast.kernels.iso.iso_interval` for the iso modes); approximate indices (the
    BIH's single- and multi-sample modes) overload it for their record.

A record class may set three class attributes (read at compile time):

``LATTICE = True``
    Intervals are marched on the global lattice with :func:`march_interval` and
    touching intervals are merged (the same samples, fewer restarts). ``False``:
    each interval goes to the record's own ``integrate``, unmerged.
``SCRATCH = False``
    The record needs no scratch; a 1-element dummy array is passed.
``TILE = False``
    The record overloads ``start_tile``; otherwise the driver neither calls it nor
    computes the tile's corner rays (``culls_tiles`` folds the test away at compile time).

Inlining. The driver is one Numba function per record type, voxel dtype, sampler,
mode and storage, so what is inlined into it is compiled again for each of these
(about 85 in the test suite). Numba's own inlining (``inline="always"``) copies and
re-types the callee's IR at every call site, recursively, and that, not LLVM, was
most of a specialisation's compile time (a cold deep k-d tree render took 45-47 s).
The rule: inline at Numba level only the iterator's ``start_ray`` /
``next_interval`` and the per-sample path (:mod:`~sparsecast.kernels.sampler`, in
:func:`~sparsecast.kernels.march.march_segment`), where a call per node or per
sample was measured to cost frame time; everything below them (slab tests, DDA
steps, stack pushes, node decoding) and everything once per ray or tile (clip
intervals, corner rays, ``start_tile``) is a plain ``@njit`` call, which LLVM still
inlines where it pays; so are the small arithmetic helpers of the per-sample path (cell
look-up, interpolation, table position), which Numba would copy at every one of their
call sites. ``integrate``'s lattice march names no record, so one cached
copy serves every index; the default ``integrate`` that calls it is two lines and is
inlined (compiled apart, it was one more 0.5 s function per record). Measured: a cold deep k-d tree render compiles in 15 s
instead of 45-47 s, the DDA grid in 3 s instead of 15 s, frames unchanged within noise.
Plain calls use ``error_model="numpy"`` like the driver (a ray parallel to an axis
divides by zero).

Adding an exact index is one package with a record class, overloads of
``start_ray`` and ``next_interval`` (and ``make_scratch`` if ``SCRATCH``), and a
``traversal_record`` method on the index class: no edit to the driver.
"""

from __future__ import annotations

import numpy as np
from numba.extending import overload

from ..kernels.iso import Iso, IsoDvr, iso_interval
from ..kernels.march import Dvr, march_interval

__all__ = ["make_scratch", "start_tile", "start_ray", "next_interval", "integrate", "coalesces", "culls_tiles",
           "record_class"]


def make_scratch(record):  # pragma: no cover - replaced by overloads in jitted code
    """Per-tile scratch of ``record`` (see the module docstring)."""
    raise NotImplementedError("make_scratch is only callable from jitted code")


def start_tile(record, scratch, corners, box, planes):  # pragma: no cover
    """Per-tile set-up of ``record``; False when no ray of the tile meets an interval (module docstring)."""
    raise NotImplementedError("start_tile is only callable from jitted code")


def start_ray(record, scratch, ray, t_lo, t_hi):  # pragma: no cover
    """Traversal state at the start of a ray (see the module docstring)."""
    raise NotImplementedError("start_ray is only callable from jitted code")


def next_interval(record, scratch, ray, state, t_covered):  # pragma: no cover
    """The next non-empty interval ``(t0, t1, state)`` (see the module docstring)."""
    raise NotImplementedError("next_interval is only callable from jitted code")


def integrate(record, scratch, state, mode, sampler, flat, nx, ny, nz, table, v_lo, scale, inv_spacing, dt, ert,
              shading, ray, wdir, t0, t1, k_next, k_min, k_max, acc):  # pragma: no cover
    """Composite one interval (see the module docstring)."""
    raise NotImplementedError("integrate is only callable from jitted code")


def coalesces(record):  # pragma: no cover
    """Whether the driver merges touching intervals of ``record`` (``LATTICE``)."""
    raise NotImplementedError("coalesces is only callable from jitted code")


def culls_tiles(record):  # pragma: no cover
    """Whether the driver calls ``start_tile`` for ``record`` (``TILE``), a compile-time constant."""
    raise NotImplementedError("culls_tiles is only callable from jitted code")


# The generic overloads below match every record type, a user's or a test's
# too, so they are not cached on their own: Numba's cache index pickles each
# signature, and a record class a later process cannot import would make that
# index unloadable. (They are compiled into the driver, whose cache is used only
# for the package's own records; see render.driver.tiles_kernel.)


def record_class(numba_type):
    """The Python class behind a record's Numba type (None for other types).

    Overloads use it to claim their record: ``record_class(record) is MyRecord``.
    """
    return getattr(numba_type, "instance_class", None)


def _lattice(numba_type) -> bool:
    return bool(getattr(record_class(numba_type), "LATTICE", True))


@overload(coalesces, inline="always")
def _coalesces(record):
    if record_class(record) is None:
        return None
    if _lattice(record):
        return lambda record: True
    return lambda record: False


@overload(culls_tiles, inline="always")
def _culls_tiles(record):
    if record_class(record) is None:
        return None
    if getattr(record_class(record), "TILE", False):
        return lambda record: True
    return lambda record: False


@overload(start_tile, inline="always")
def _no_tile(record, scratch, corners, box, planes):
    # Typed (Numba types both sides of the driver's culls_tiles branch), never run.
    cls = record_class(record)
    if cls is None or getattr(cls, "TILE", False):
        return None
    return lambda record, scratch, corners, box, planes: True


@overload(make_scratch, inline="always")
def _no_scratch(record):
    cls = record_class(record)
    if cls is None or getattr(cls, "SCRATCH", False):
        return None

    def impl(record):
        return np.empty(1, np.int64)

    return impl


@overload(integrate, inline="always")
def _integrate_lattice(record, scratch, state, mode, sampler, flat, nx, ny, nz, table, v_lo, scale, inv_spacing,
                       dt, ert, shading, ray, wdir, t0, t1, k_next, k_min, k_max, acc):
    if record_class(record) is None or not _lattice(record):
        return None
    kind = getattr(mode, "instance_class", None)
    if kind is Dvr:
        def impl(record, scratch, state, mode, sampler, flat, nx, ny, nz, table, v_lo, scale, inv_spacing, dt,
                 ert, shading, ray, wdir, t0, t1, k_next, k_min, k_max, acc):
            ox, oy, oz, dx, dy, dz = ray
            wdx, wdy, wdz = wdir
            r, g, b, a = acc
            return march_interval(
                sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
                wdx, wdy, wdz, inv_spacing, dt, t0, t1, k_next, k_max, r, g, b, a, ert, shading,
            )

        return impl
    if kind is Iso or kind is IsoDvr:
        def impl(record, scratch, state, mode, sampler, flat, nx, ny, nz, table, v_lo, scale, inv_spacing, dt,
                 ert, shading, ray, wdir, t0, t1, k_next, k_min, k_max, acc):
            return iso_interval(mode, sampler, flat, nx, ny, nz, table, v_lo, scale, ray, wdir, inv_spacing,
                                dt, t0, t1, k_next, k_min, k_max, acc, ert, shading)

        return impl
    return None
