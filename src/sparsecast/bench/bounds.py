"""How few samples an exact skipper that decides by cells can take: the *cell bound*.

The bench's oracle (``samples_nonempty``) counts the samples of non-zero opacity. No
exact index can skip below it, but none can reach it either: an index decides which
space is empty from ranges of voxel values (a cell's eight corners at the finest), and
a sample in a cell whose range meets the TF's visible values must be taken to learn
that its own interpolated value is transparent. The cell bound counts the naive
marcher's samples (same lattice, same early termination) that fall in such an
*occupied cell*: the samples of a perfect skipper at cell granularity. Its ratio to the
oracle says how much of an index's ``samples / oracle`` any cell-exact index must
pay; the rest is the index's own granularity (leaves, bricks, macrocells).

Occupancy is computed here with NumPy from the voxels and the TF table, independently
of the indices' own classification: a cell is occupied when the table has a visible
entry among those that interpolation between its corner minimum and maximum reads.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..kernels.camera import index_space_ray
from ..kernels.ray import clip_lattice
from ..kernels.sample import trilinear
from ..kernels.shade import tf_alpha

__all__ = ["cell_occupancy", "volume_occupancy", "cell_bound"]


def cell_occupancy(data: np.ndarray, table: np.ndarray, v_lo: float, scale: float) -> np.ndarray:
    """Which cells a TF table makes visible somewhere.

    Parameters
    ----------
    data : (nz, ny, nx) ndarray
        Voxels.
    table : (n, 4) float32
        Step-corrected TF table (opacity in column 3), read as
        :func:`sparsecast.kernels.shade.tf_alpha` reads it.
    v_lo, scale : float
        The value at entry 0 and entries per data unit.

    Returns
    -------
    (max(nz-1, 1), max(ny-1, 1), max(nx-1, 1)) bool
        Cell ``(k, j, i)`` (between voxels ``k..k+1``, ``j..j+1``, ``i..i+1``) is
        occupied when some entry with non-zero opacity lies in
        ``[floor(x_lo), floor(x_hi) + 1]``, ``x`` the table positions of its corner
        range (conservative: it covers every interpolated value of the cell).
    """
    f = np.asarray(data, np.float64)
    lo, hi = f, f
    for axis in range(3):
        if f.shape[axis] > 1:
            a = [slice(None)] * 3
            b = [slice(None)] * 3
            a[axis] = slice(None, -1)
            b[axis] = slice(1, None)
            lo = np.minimum(lo[tuple(a)], lo[tuple(b)])
            hi = np.maximum(hi[tuple(a)], hi[tuple(b)])
    n = table.shape[0]
    visible = np.concatenate([[0], np.cumsum(np.asarray(table)[:, 3] > 0.0)])
    # A margin of 1e-9 entries covers the rounding of the interpolated value near a corner.
    first = np.clip(np.floor((lo - v_lo) * scale - 1e-9), 0, n - 1).astype(np.int64)
    last = np.clip(np.floor((hi - v_lo) * scale + 1e-9) + 1, 0, n - 1).astype(np.int64)
    return (visible[last + 1] - visible[first]) > 0


@njit(cache=True, parallel=True)
def _count(flat, nx, ny, nz, occ, table, v_lo, scale, cam, width, height, origin, inv_spacing, dt, ert, out):
    ocx, ocy = occ.shape[2], occ.shape[1]
    occ_flat = occ.reshape(-1)
    for py in prange(height):
        taken = 0
        nonempty = 0
        in_cells = 0
        for px in range(width):
            ox, oy, oz, dx, dy, dz, _, _, _ = index_space_ray(cam, px, py, width, height, origin, inv_spacing)
            k, k_hi, _, _ = clip_lattice(ox, oy, oz, dx, dy, dz, 0.0, 0.0, 0.0, nx - 1.0, ny - 1.0, nz - 1.0,
                                         False, False, False, False, False, False, False, dt)
            acc = 0.0
            while k <= k_hi and acc < ert:
                t = k * dt
                x = ox + t * dx
                y = oy + t * dy
                z = oz + t * dz
                _, _, a = tf_alpha(table, trilinear(flat, nx, ny, nz, x, y, z), v_lo, scale)
                taken += 1
                # The cell the sampler reads (sample._axis's clamped lower corner).
                ci = min(max(int(x), 0), ocx - 1)
                cj = min(max(int(y), 0), ocy - 1)
                ck = min(max(int(z), 0), occ.shape[0] - 1)
                if occ_flat[(ck * ocy + cj) * ocx + ci]:
                    in_cells += 1
                if a > 0.0:
                    nonempty += 1
                    acc += (1.0 - acc) * a  # the driver's compositing of opacity: same termination
                k += 1
        out[py, 0] = taken
        out[py, 1] = nonempty
        out[py, 2] = in_cells


def _table(volume, tf, dt: float) -> np.ndarray:
    """The frame's step-corrected TF table, as :func:`sparsecast.render.render` makes it."""
    unit = tf.unit_distance if tf.unit_distance is not None else float(np.min(volume.spacing))
    return np.ascontiguousarray(tf.opacity_table(dt, unit), dtype=np.float32)


def volume_occupancy(volume, tf, dt: float) -> np.ndarray:
    """:func:`cell_occupancy` of ``volume`` under ``tf``'s table for step ``dt`` (one per
    volume, TF and step: every view of a case shares it)."""
    return np.ascontiguousarray(cell_occupancy(volume.data, _table(volume, tf, dt), float(tf.value_range[0]),
                                               float(tf.scale)))


def cell_bound(volume, tf, camera, width: int, height: int, dt: float, ert: float = 0.99, *,
               occupancy: np.ndarray | None = None) -> dict[str, int] | None:
    """Samples of the naive marcher, of non-zero opacity, and in occupied cells, for one frame.

    Parameters
    ----------
    volume : Volume
        A dense volume (its ``data``).
    tf : TransferFunction
        Trilinear sampling only (None is returned for label TFs).
    camera : Camera
    width, height : int
    dt, ert : float
        The frame's lattice step and early-termination threshold.
    occupancy : ndarray, optional
        :func:`volume_occupancy` of this volume, TF and ``dt``, when the caller keeps it
        across views (computed here otherwise).

    Returns
    -------
    dict or None
        ``samples`` and ``samples_nonempty`` (equal to a naive render's stats) and
        ``samples_cell_bound``; None when the TF does not sample trilinearly.
    """
    if getattr(tf, "sampling", "trilinear") != "trilinear":
        return None
    data = np.ascontiguousarray(volume.data)
    table = _table(volume, tf, dt)
    v_lo, scale = float(tf.value_range[0]), float(tf.scale)
    occ = volume_occupancy(volume, tf, dt) if occupancy is None else occupancy
    nz, ny, nx = data.shape
    out = np.zeros((height, 3), np.int64)
    _count(data.reshape(-1), nx, ny, nz, occ, table, v_lo, scale,
           np.ascontiguousarray(camera.ray_params(width, height), dtype=np.float64), width, height,
           np.ascontiguousarray(volume.origin, dtype=np.float64),
           np.ascontiguousarray(1.0 / np.asarray(volume.spacing, np.float64)), float(dt), float(ert), out)
    s = out.sum(axis=0)
    return {"samples": int(s[0]), "samples_nonempty": int(s[1]), "samples_cell_bound": int(s[2])}
