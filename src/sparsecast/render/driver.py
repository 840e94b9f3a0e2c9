"""The one DVR driver: per-tile ray set-up, clipping, interval coalescing, lattice
marching, early termination, compositing and counting, for every index.

An index enters only through its record and the four functions of
:mod:`sparsecast.index.interval`, dispatched on the record's type, so one
source serves every index and ``cache=True`` keeps the compiled kernels across
processes (one specialisation per record type and voxel dtype).

Exactness. Every sample is taken at a global lattice index ``k`` through
:func:`sparsecast.kernels.march.march_segment`, whatever the index, and in
increasing ``k``: intervals come front to back; a run of touching intervals is
marched as one segment, and ``k_next`` (the first index not taken yet) is passed
from one segment to the next, so no sample is taken twice. Merging touching
intervals takes exactly the lattice indices that marching them one by one with
``k_next`` would, so it changes no float. ``[k_lo, k_hi]`` from
:func:`~sparsecast.kernels.ray.clip_lattice` bounds every segment, so an index
may yield intervals reaching past the clip box.
"""

from __future__ import annotations

import math

from numba import njit

from ..index.interval import coalesces, integrate, make_scratch, next_interval, start_ray
from ..kernels.camera import index_space_ray
from ..kernels.ray import clip_lattice
from ..kernels.shade import write_pixel
from ..kernels.tiles import tile_bounds

__all__ = ["dvr_tile", "dvr_tiles"]


@njit(cache=True, error_model="numpy")
def dvr_tile(tile, record, data, frame, init, out_rgba, out_samples, out_nonempty):
    """Render the pixels of one 8x8 tile of the output rectangle.

    Parameters
    ----------
    tile : int
        Tile number in the output rectangle (row-major, see :mod:`.kernels.tiles`).
    record : NamedTuple
        The index's traversal record (:mod:`sparsecast.index.interval`).
    data : (nz, ny, nx) ndarray
        Voxels, C-contiguous.
    frame : Frame
        See :class:`sparsecast.render.frame.Frame`.
    init : (h, w, 4) float32 or (0, 0, 4)
        Premultiplied RGBA accumulated in front of the clip box (a ray another
        piece started), or an empty array for none.
    out_rgba : (h, w, 4) float32
        Premultiplied result composited over ``frame.background``.
    out_samples, out_nonempty : (h, w) int32
        Samples taken, and samples of non-zero opacity, per pixel.
    """
    nz, ny, nx = data.shape
    vol = (data.reshape(nz * ny * nx), nx, ny, nz)  # a view of the C-ordered voxels
    h, w = out_samples.shape
    has_init = init.shape[0] > 0
    merge = coalesces(record)
    scratch = make_scratch(record)
    x0, x1, y0, y1 = tile_bounds(tile, w, h)
    for py in range(y0, y1):
        for px in range(x0, x1):
            ox, oy, oz, dx, dy, dz, wdx, wdy, wdz = index_space_ray(
                frame.cam, frame.x0 + px, frame.y0 + py, frame.width, frame.height,
                frame.origin, frame.inv_spacing,
            )
            ray = (ox, oy, oz, dx, dy, dz)
            wdir = (wdx, wdy, wdz)
            if has_init:
                acc = (float(init[py, px, 0]), float(init[py, px, 1]), float(init[py, px, 2]),
                       float(init[py, px, 3]))
            else:
                acc = (0.0, 0.0, 0.0, 0.0)
            n_samples = 0
            n_nonempty = 0
            k_lo, k_hi, t_lo, t_hi = clip_lattice(
                (ox, oy, oz), (dx, dy, dz), frame.clip_lo, frame.clip_hi, frame.open_lo, frame.open_hi,
                frame.dt,
            )
            if k_lo <= k_hi and acc[3] < frame.ert:
                state = start_ray(record, scratch, ray, t_lo, t_hi)
                k_next = k_lo
                seg_open = False
                seg_t0 = 0.0
                seg_t1 = -math.inf
                while True:
                    t0, t1, state = next_interval(record, scratch, ray, state,
                                                  seg_t1 if seg_open else -math.inf)
                    more = t0 <= t1
                    if merge:
                        # A touching interval extends the open segment.
                        if more and seg_open and t0 <= seg_t1:
                            if t1 > seg_t1:
                                seg_t1 = t1
                            continue
                        if seg_open:
                            r, g, b, a, k_next, ns, nne = integrate(
                                record, scratch, state, vol, frame, ray, wdir, seg_t0, seg_t1,
                                k_next, k_hi, acc,
                            )
                            acc = (r, g, b, a)
                            n_samples += ns
                            n_nonempty += nne
                            if a >= frame.ert:
                                break
                        if not more:
                            break
                        seg_open = True
                        seg_t0 = t0
                        seg_t1 = t1
                    else:
                        if not more:
                            break
                        t0 = max(t0, t_lo)
                        t1 = min(t1, t_hi)
                        if t0 > t1:
                            continue
                        r, g, b, a, k_next, ns, nne = integrate(
                            record, scratch, state, vol, frame, ray, wdir, t0, t1, k_next, k_hi, acc,
                        )
                        acc = (r, g, b, a)
                        n_samples += ns
                        n_nonempty += nne
                        if a >= frame.ert:
                            break
            write_pixel(out_rgba, py, px, acc[0], acc[1], acc[2], acc[3], frame.background)
            out_samples[py, px] = n_samples
            out_nonempty[py, px] = n_nonempty


@njit(cache=True, nogil=True)
def dvr_tiles(first, last, record, data, frame, init, out_rgba, out_samples, out_nonempty):
    """Render tiles ``first..last-1`` (see :func:`dvr_tile`), without the GIL.

    The frame is spread over threads by :func:`sparsecast.render.schedule.run_tiles`
    rather than ``prange``: Numba's parallel loops cannot take records (tuples of
    arrays) as arguments, and chunks handed out by a pool balance the load of
    sparse frames and let a caller stop between chunks.
    """
    for tile in range(first, last):
        dvr_tile(tile, record, data, frame, init, out_rgba, out_samples, out_nonempty)
