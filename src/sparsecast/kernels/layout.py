"""Which voxel layout a kernel argument holds, and the layout-independent ways to read it.

Two layouts reach the kernels: a dense C-ordered ``(nz, ny, nx)`` array, and a
bricked volume's :class:`~.bricked.BrickedVoxels` (page table and pool). Kernels
that read voxels take either and call the functions here (and
:func:`.sampler.sample`), which are resolved at compile time on the argument's
Numba type: each layout gets its own specialisation, with no branch in the loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import overload

from .bricked import BrickedVoxels, bricked_offset

__all__ = ["layout_of", "voxel_view", "voxel_parts", "row_offset"]


def layout_of(numba_type) -> str | None:
    """``"dense"`` for a 1-D or 3-D array type, ``"bricked"`` for :class:`BrickedVoxels`, else None."""
    if isinstance(numba_type, types.Array):
        return "dense"
    if getattr(numba_type, "instance_class", None) is BrickedVoxels:
        return "bricked"
    return None


def voxel_view(data):  # pragma: no cover - replaced by overloads in jitted code
    """``(flat, nx, ny, nz)`` for the samplers: a dense ``(nz, ny, nx)`` array as its 1-D
    view, a :class:`~.bricked.BrickedVoxels` as itself."""
    raise NotImplementedError("voxel_view is only callable from jitted code")


@overload(voxel_view, inline="always")
def _voxel_view(data):
    if isinstance(data, types.Array) and data.ndim == 3:
        def dense(data):
            nz, ny, nx = data.shape
            return data.reshape(nz * ny * nx), nx, ny, nz

        return dense
    if layout_of(data) == "bricked":
        return lambda data: (data, data.nx, data.ny, data.nz)
    return None


def voxel_parts(data):  # pragma: no cover - replaced by overloads in jitted code
    """``(values, pages, nx, ny, nz, nbx, nby, shift)``: the voxels as plain arrays and scalars.

    For kernels with ``prange`` loops, whose bodies cannot take records (Numba's
    parfor lowering fails on tuple variables). ``values`` is the dense 1-D view or
    the bricked pool; ``pages`` the page table (empty for dense) and ``shift`` is
    ``log2(B)`` (-1 for dense). Read rows with :func:`row_offset`.
    """
    raise NotImplementedError("voxel_parts is only callable from jitted code")


@overload(voxel_parts, inline="always")
def _voxel_parts(data):
    if isinstance(data, types.Array) and data.ndim == 3:
        def dense(data):
            nz, ny, nx = data.shape
            return data.reshape(nz * ny * nx), np.empty(0, np.int32), nx, ny, nz, 0, 0, -1

        return dense
    if layout_of(data) == "bricked":
        return lambda data: (data.pool, data.pages, data.nx, data.ny, data.nz, data.nbx, data.nby, data.shift)
    return None


@njit(cache=True, inline="always")
def row_offset(pages, shift, nbx, nby, nx, ny, cz, cy, cx, k, j):
    """Offset with voxel ``(k, j, i)`` at ``values[offset + i]`` (see :func:`voxel_parts`).

    Bricked: the row is read from the slot of the storage brick holding cell
    ``(cz, cy, cx)``; the voxels must lie in its stored window (its cells and a
    one-voxel apron) and the brick must be resident (else -1 is returned).
    """
    if shift < 0:
        return (k * ny + j) * nx
    return bricked_offset(pages, shift, nbx, nby, cz >> shift, cy >> shift, cx >> shift, k, j)
