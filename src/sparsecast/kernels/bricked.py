"""Bricked voxel storage on the kernel side: a page table over a pool of bricks.

A bricked volume (:class:`sparsecast.storage.BrickedVolume`) keeps only some
bricks of ``B^3`` cells in memory. Brick ``(bz, by, bx)`` covers the cells
between voxels ``b*B`` and ``(b+1)*B`` on each axis; its pool slot holds the
voxels ``[b*B - 1, (b+1)*B + 1]`` per axis (``E = B + 3`` of them): the
trilinear footprint of its cells plus the one-voxel apron that a
central-difference gradient at any point of its cells reads, and that the brick
statistics (:func:`sparsecast.kernels.bricks.brick_minmax`) range over. A brick
with no slot reads as its ``fill`` value: the background for a brick whose
every voxel (apron included) is background, which is then exact, or, for a
brick that is merely not resident, a value of its range that the current
transfer function maps to zero opacity (see the storage module for why that
leaves every image unchanged).

Exactness. :func:`bricked_trilinear` picks the cell of a point exactly as the
dense :func:`sparsecast.kernels.sample.trilinear` does (same clamping, same
fraction), reads the same eight voxel values from the slot and interpolates
in the same order, so the two return the same float. A gradient reads its six
neighbours from the slot of the centre's brick (they lie in its apron), so a
resident brick alone shades every sample inside it.

The record's type is what :mod:`sparsecast.kernels.sampler` dispatches on, so
a dense and a bricked volume compile to separate loops, each without a branch
on the layout.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
from numba import njit, prange
from numba.core.errors import NumbaIRAssumptionWarning

from .sample import lerp8

# Inlining the bricked sampler into the iso modes' inlined sample-at-t helper trips a
# pedantic scope check in Numba's IR inliner (the inlined result variable is reported
# "not in scope"); the compiled code is right (tests/storage: iso modes equal dense), and
# not inlining costs the iso modes about 2x. Silence exactly that report.
warnings.filterwarnings("ignore", category=NumbaIRAssumptionWarning,
                        message=r"variable '_sample__locals___lambda__\w*bricked_[\w.]*' is not in scope")

__all__ = [
    "BrickedVoxels",
    "bricked_trilinear",
    "bricked_nearest",
    "bricked_corners",
    "bricked_gradient",
    "bricked_offset",
    "gather_brick",
    "gather_bricks",
    "gather_bricks_serial",
]

class BrickedVoxels(NamedTuple):
    """The kernel-side view of a bricked volume (see the module docstring).

    Attributes
    ----------
    pool : (n_slots * E^3,) ndarray
        Slot ``s`` is ``pool[s*E^3:(s+1)*E^3]``, a C-ordered ``(E, E, E)`` block
        (``E = B + 3``) of the volume's dtype; voxel ``(k, j, i)`` of brick ``b``
        sits at local ``(k - bz*B + 1, j - by*B + 1, i - bx*B + 1)``.
    pages : (nbz * nby * nbx,) int32
        Slot of each brick (flat ``(bz * nby + by) * nbx + bx``), or -1.
    fill : (nbz * nby * nbx,) float64
        Value a brick without a slot reads as.
    nx, ny, nz : int
        Voxel counts.
    nbx, nby : int
        Brick counts along x and y.
    shift : int
        ``log2(B)``; bricks are powers of two so that the brick of a cell is a shift.
    """

    pool: np.ndarray
    pages: np.ndarray
    fill: np.ndarray
    nx: int
    ny: int
    nz: int
    nbx: int
    nby: int
    shift: int


@njit(cache=True)
def _cell(x, n):
    """Lower voxel, step to the upper one and fraction: :func:`..sample._axis`'s cell."""
    i0 = min(max(int(x), 0), max(n - 2, 0))
    return i0, min(n - 1, 1), x - i0


@njit(cache=True, inline="always")
def _brick(vox, i0, j0, k0):
    """Brick ``(bx, by, bz)`` of cell ``(k0, j0, i0)`` and its flat number."""
    s = vox.shift
    bx = i0 >> s
    by = j0 >> s
    bz = k0 >> s
    return bx, by, bz, (bz * vox.nby + by) * vox.nbx + bx


@njit(cache=True, inline="always")
def _slot_base(vox, slot, bx, by, bz, i, j, k):
    """Pool offset of voxel ``(k, j, i)`` in the slot of brick ``(bz, by, bx)``."""
    s = vox.shift
    e = (1 << s) + 3
    return (((slot * e + (k - (bz << s) + 1)) * e) + (j - (by << s) + 1)) * e + (i - (bx << s) + 1)


@njit(cache=True, inline="always")
def _lerp8(pool, base, si, sj, sk, fx, fy, fz):
    """The dense interpolation (:func:`..sample.lerp8`) of the cell at ``pool[base]``."""
    return lerp8(float(pool[base]), float(pool[base + si]), float(pool[base + sj]), float(pool[base + sj + si]),
                 float(pool[base + sk]), float(pool[base + sk + si]), float(pool[base + sk + sj]),
                 float(pool[base + sk + sj + si]), fx, fy, fz)


@njit(cache=True, inline="always")
def _slot_lerp(vox, slot, bx, by, bz, x, y, z):
    """Trilinear value at ``(x, y, z)`` read from the slot of brick ``(bz, by, bx)``.

    The point's cell must lie in the brick's stored window (``[b*B - 1, (b+1)*B + 1]``):
    its own cells, and the gradient's neighbours of any point in them.
    """
    i0, si, fx = _cell(x, vox.nx)
    j0, sj, fy = _cell(y, vox.ny)
    k0, sk, fz = _cell(z, vox.nz)
    e = (1 << vox.shift) + 3
    return _lerp8(vox.pool, _slot_base(vox, slot, bx, by, bz, i0, j0, k0), si, sj * e, sk * e * e, fx, fy, fz)


@njit(cache=True, inline="always")
def bricked_trilinear(vox, x, y, z):
    """Trilinear value at index-space point ``(x, y, z)``; equal to the dense one."""
    i0, _, _ = _cell(x, vox.nx)
    j0, _, _ = _cell(y, vox.ny)
    k0, _, _ = _cell(z, vox.nz)
    bx, by, bz, b = _brick(vox, i0, j0, k0)
    slot = np.int64(vox.pages[b])
    # Inlined (worth ~25 % against a call per sample), with one return.
    v = vox.fill[b]
    if slot >= 0:
        v = _slot_lerp(vox, slot, bx, by, bz, x, y, z)
    return v


@njit(cache=True, inline="always")
def bricked_nearest(vox, x, y, z):
    """Value of the voxel nearest to ``(x, y, z)``; equal to :func:`..sampler.nearest`.

    The voxel ``floor(x + 0.5)`` (clamped) is a corner of the point's cell, so it
    is read from the slot of that cell's brick.
    """
    nx = vox.nx
    ny = vox.ny
    nz = vox.nz
    i0, _, _ = _cell(x, nx)
    j0, _, _ = _cell(y, ny)
    k0, _, _ = _cell(z, nz)
    bx, by, bz, b = _brick(vox, i0, j0, k0)
    slot = np.int64(vox.pages[b])
    v = vox.fill[b]
    if slot >= 0:  # one return (see bricked_trilinear)
        i = min(max(int(x + 0.5), 0), nx - 1)
        j = min(max(int(y + 0.5), 0), ny - 1)
        k = min(max(int(z + 0.5), 0), nz - 1)
        v = float(vox.pool[_slot_base(vox, slot, bx, by, bz, i, j, k)])
    return v


@njit(cache=True)
def bricked_corners(vox, x, y, z):
    """The eight corner values of the cell of ``(x, y, z)`` and its fractions, as the
    dense :func:`..sample.corners` returns them (same cell, same order).

    All eight lie in the slot of the cell's brick; a brick without a slot gives its
    fill value at every corner.
    """
    i0, si, fx = _cell(x, vox.nx)
    j0, sj, fy = _cell(y, vox.ny)
    k0, sk, fz = _cell(z, vox.nz)
    bx, by, bz, b = _brick(vox, i0, j0, k0)
    slot = np.int64(vox.pages[b])
    if slot < 0:
        v = vox.fill[b]
        return v, v, v, v, v, v, v, v, fx, fy, fz
    e = (1 << vox.shift) + 3
    base = _slot_base(vox, slot, bx, by, bz, i0, j0, k0)
    pool = vox.pool
    sj = sj * e
    sk = sk * e * e
    return (
        float(pool[base]), float(pool[base + si]), float(pool[base + sj]), float(pool[base + sj + si]),
        float(pool[base + sk]), float(pool[base + sk + si]), float(pool[base + sk + sj]),
        float(pool[base + sk + sj + si]), fx, fy, fz,
    )


@njit(cache=True)
def _clamp(x, n):
    return min(max(x, 0.0), n - 1.0)


@njit(cache=True)
def bricked_gradient(vox, x, y, z):
    """Central-difference gradient of :func:`..sample.gradient_clamped` on the dense volume:
    the same as :func:`..sample.gradient` up to rounding (which takes a faster path inside).

    Neighbours are clamped to the box as there. When the centre's brick has a slot
    all six neighbours are read from it (they lie in its apron); otherwise each is
    looked up on its own (a brick without a slot is uniform, its neighbours may not be).
    """
    nx = vox.nx
    ny = vox.ny
    nz = vox.nz
    x0 = _clamp(x - 1.0, nx)
    y0 = _clamp(y - 1.0, ny)
    z0 = _clamp(z - 1.0, nz)
    x1 = _clamp(x + 1.0, nx)
    y1 = _clamp(y + 1.0, ny)
    z1 = _clamp(z + 1.0, nz)
    i0, _, _ = _cell(x, nx)
    j0, _, _ = _cell(y, ny)
    k0, _, _ = _cell(z, nz)
    bx, by, bz, b = _brick(vox, i0, j0, k0)
    slot = np.int64(vox.pages[b])
    if slot < 0:
        gx = 0.5 * (bricked_trilinear(vox, x1, y, z) - bricked_trilinear(vox, x0, y, z))
        gy = 0.5 * (bricked_trilinear(vox, x, y1, z) - bricked_trilinear(vox, x, y0, z))
        gz = 0.5 * (bricked_trilinear(vox, x, y, z1) - bricked_trilinear(vox, x, y, z0))
        return gx, gy, gz
    gx = 0.5 * (_slot_lerp(vox, slot, bx, by, bz, x1, y, z) - _slot_lerp(vox, slot, bx, by, bz, x0, y, z))
    gy = 0.5 * (_slot_lerp(vox, slot, bx, by, bz, x, y1, z) - _slot_lerp(vox, slot, bx, by, bz, x, y0, z))
    gz = 0.5 * (_slot_lerp(vox, slot, bx, by, bz, x, y, z1) - _slot_lerp(vox, slot, bx, by, bz, x, y, z0))
    return gx, gy, gz


@njit(cache=True, inline="always")
def bricked_offset(pages, shift, nbx, nby, bz, by, bx, k, j):
    """Offset in the pool with voxel ``(k, j, i)`` at ``offset + i``, from the slot of brick
    ``(bz, by, bx)``; ``(k, j, i)`` must lie in its stored window. -1 when it has no slot."""
    slot = np.int64(pages[(bz * nby + by) * nbx + bx])
    if slot < 0:
        return np.int64(-1)
    e = (1 << shift) + 3
    return (((slot * e + (k - (bz << shift) + 1)) * e) + (j - (by << shift) + 1)) * e + 1 - (bx << shift)


@njit(cache=True, nogil=True)
def gather_brick(block, z0, y0, x0, bz, by, bx, slot, brick, nz, ny, nx, pool):
    """Copy one brick's stored window out of ``block`` into ``pool[slot]`` (see :func:`gather_bricks`)."""
    e = brick + 3
    gz = bz * brick - 1
    gy = by * brick - 1
    gx = bx * brick - 1
    for c in range(e):
        k = min(max(gz + c, 0), nz - 1) - z0
        for r in range(e):
            j = min(max(gy + r, 0), ny - 1) - y0
            for q in range(e):
                i = min(max(gx + q, 0), nx - 1) - x0
                pool[slot, c, r, q] = block[k, j, i]


@njit(cache=True, nogil=True)
def gather_bricks_serial(block, z0, y0, x0, bz, by, bx, slots, brick, nz, ny, nx, pool):
    """:func:`gather_bricks` on the calling thread, without the GIL: for reader threads,
    which must not each start a team of Numba's parallel threads."""
    for n in range(bz.shape[0]):
        gather_brick(block, z0, y0, x0, bz[n], by[n], bx[n], slots[n], brick, nz, ny, nx, pool)


@njit(cache=True, parallel=True)
def gather_bricks(block, z0, y0, x0, bz, by, bx, slots, brick, nz, ny, nx, pool):
    """Copy the stored windows of some bricks out of a block of voxels into their slots.

    Parameters
    ----------
    block : (lz, ly, lx) ndarray
        Voxels ``[z0, z0+lz) x [y0, y0+ly) x [x0, x0+lx)`` of the volume; it must hold
        each listed brick's window clipped to the volume.
    z0, y0, x0 : int
        Global index of ``block[0, 0, 0]``.
    bz, by, bx : (n,) int64
        The bricks to copy.
    slots : (n,) int64
        Their slots.
    brick : int
        ``B``.
    nz, ny, nx : int
        Volume dims (the window is clipped to them; window voxels outside the volume
        take the value of the nearest voxel inside, and are never read by a sample).
    pool : (n_slots, E, E, E) ndarray
        Written in place.
    """
    for n in prange(bz.shape[0]):
        gather_brick(block, z0, y0, x0, bz[n], by[n], bx[n], slots[n], brick, nz, ny, nx, pool)
