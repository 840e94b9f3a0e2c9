"""The one DVR driver: per-tile ray set-up, clipping, interval coalescing, lattice
marching, early termination, compositing and counting, for every index.

An index enters only through its record and the functions of
:mod:`sparsecast.index.interval`, dispatched on the record's type, so one
source serves every index and ``cache=True`` keeps the compiled kernels across
processes (one specialisation per record type and voxel dtype). The iterator's
``start_ray`` / ``next_interval`` are inlined into the loop; the loop and every
plain kernel it calls compile without reference counting
(:data:`sparsecast.kernels.borrow.NO_REFCOUNT`): counting the arrays it reads had
made the deep k-d tree 1.7x slower, and the calls into the runtime that borrowed
views still paid took 6 % of its isosurface frames.

Exactness. Every sample is taken at a global lattice index ``k`` through
:func:`sparsecast.kernels.march.march_segment`, whatever the index, and in
increasing ``k``: intervals come front to back; a run of touching intervals is
marched as one segment, and ``k_next`` (the first index not taken yet) is passed
from one segment to the next, so no sample is taken twice. Merging touching
intervals takes exactly the lattice indices that marching them one by one with
``k_next`` would, so it changes no float. ``[k_lo, k_hi]`` from
:func:`~sparsecast.kernels.ray.clip_lattice` bounds every segment, so an index
may yield intervals reaching past the clip box.

Clip caps. With ``frame.cap`` on, a ray whose clipped interval starts on a cut
face (a clip-box face inside the volume, or a clip plane) takes its first
lattice sample ``k_lo`` here, shaded with the face's normal
(:func:`~sparsecast.kernels.march.cap_sample`), and the index's intervals are
marched from ``k_lo + 1``: a per-ray decision before any traversal, the same for
every index, and no branch in the marching loop.
"""

from __future__ import annotations

import math

from numba import njit

from ..index.interval import coalesces, culls_tiles, integrate, make_scratch, next_interval, start_ray, start_tile
from ..kernels.borrow import NO_REFCOUNT
from ..kernels.camera import index_space_ray, tile_corner_rays
from ..kernels.march import cap_sample
from ..kernels.ray import clip_lattice, clip_planes, entry_face
from ..kernels.layout import voxel_view
from ..kernels.shade import write_pixel
from ..kernels.tiles import tile_bounds

__all__ = ["dvr_tiles", "dvr_tiles_uncached", "new_scratch", "render_chunk", "render_chunk_uncached",
           "tiles_kernel"]


@njit(cache=True, inline="always")
def _initial(init, has_init, py, px):
    """The premultiplied RGBA a ray starts from: ``init``'s pixel, or transparent."""
    if has_init:
        return float(init[py, px, 0]), float(init[py, px, 1]), float(init[py, px, 2]), float(init[py, px, 3])
    return 0.0, 0.0, 0.0, 0.0


# The tile loop is written out in dvr_tiles, not a function of its own: compiled
# apart, it was linked into its caller's module and optimised and emitted again
# there (about 0.7 s of LLVM a specialisation), and inlined by Numba
# (inline="always") its IR was deep-copied and re-typed in every specialisation.
# Written out, the frame's fields are also read once per chunk, not once per tile.
# Measured (cold, 28 specialisations in one process: seven indices x DVR / iso x
# uint8 / float32): 107 s inlined, 86 s written out.
@njit(cache=True, nogil=True, error_model="numpy", **NO_REFCOUNT)
def dvr_tiles(first, last, record, scratch, data, frame, init, out_rgba, out_samples, out_nonempty):
    """Render the pixels of 8x8 tiles ``first..last-1`` of the output rectangle, without the GIL.

    The frame is spread over threads by :func:`sparsecast.render.schedule.run_tiles`
    rather than ``prange``: Numba's parallel loops cannot take records (tuples of
    arrays) as arguments, and pieces taken one at a time balance the load of
    sparse frames and let a caller stop between pieces. The loop allocates nothing
    and runs without reference counting (:data:`sparsecast.kernels.borrow.NO_REFCOUNT`):
    the caller holds every argument.

    Parameters
    ----------
    first, last : int
        Tile numbers (row-major, see :mod:`.kernels.tiles`).
    record : NamedTuple
        The index's traversal record (:mod:`sparsecast.index.interval`).
    scratch : ndarray
        The record's scratch (:func:`new_scratch`), one per chunk, reused from tile to tile.
    data : (nz, ny, nx) ndarray or BrickedVoxels
        Voxels: a C-contiguous array, or a bricked volume's page table and pool
        (:mod:`sparsecast.kernels.bricked`); each compiles its own loop.
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
    h, w = out_samples.shape
    has_init = init.shape[0] > 0
    merge = coalesces(record)
    flat, nx, ny, nz = voxel_view(data)  # a dense volume's 1-D view, or a bricked one's pages
    cam = frame.cam
    origin = frame.origin
    inv_spacing = frame.inv_spacing
    table = frame.table
    sampler = frame.sampler
    mode = frame.mode
    shading = frame.shading
    background = frame.background
    v_lo = frame.v_lo
    scale = frame.scale
    dt = frame.dt
    ert = frame.ert
    width = frame.width
    height = frame.height
    fx0 = frame.x0
    fy0 = frame.y0
    lo = frame.clip_lo
    hi = frame.clip_hi
    olo = frame.open_lo
    ohi = frame.open_hi
    cx0, cy0, cz0, cx1, cy1, cz1 = lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
    ox0, oy0, oz0, ox1, oy1, oz1 = olo[0], olo[1], olo[2], ohi[0], ohi[1], ohi[2]
    any_open = frame.any_open
    planes = frame.planes
    cap = frame.cap
    capping = cap[0] != 0.0
    cut_lo = frame.cut_lo
    cut_hi = frame.cut_hi
    for tile in range(first, last):
        x0, x1, y0, y1 = tile_bounds(tile, w, h)
        # Indices that cull once per tile (interval.start_tile) see the tile's corner rays
        # and the clip (box and planes); for the others the branch folds away at compile
        # time, corner rays included.
        live = True
        if culls_tiles(record):
            live = start_tile(
                record, scratch,
                tile_corner_rays(cam, fx0 + x0, fx0 + x1, fy0 + y0, fy0 + y1, width, height, origin, inv_spacing),
                (cx0, cy0, cz0, cx1, cy1, cz1), planes,
            )
        if not live and not capping:
            # No ray of the tile meets an interval (and no cap sample is due): each pixel is
            # what it would be after a traversal that yields nothing, without the ray set-up.
            for py in range(y0, y1):
                for px in range(x0, x1):
                    r, g, b, a = _initial(init, has_init, py, px)
                    write_pixel(out_rgba, py, px, r, g, b, a, background)
                    out_samples[py, px] = 0
                    out_nonempty[py, px] = 0
            continue
        for py in range(y0, y1):
            for px in range(x0, x1):
                ox, oy, oz, dx, dy, dz, wdx, wdy, wdz = index_space_ray(
                    cam, fx0 + px, fy0 + py, width, height, origin, inv_spacing,
                )
                ray = (ox, oy, oz, dx, dy, dz)
                r, g, b, a = _initial(init, has_init, py, px)
                n_samples = 0
                n_nonempty = 0
                k_lo, k_hi, t_lo, t_hi = clip_lattice(
                    ox, oy, oz, dx, dy, dz, cx0, cy0, cz0, cx1, cy1, cz1,
                    ox0, oy0, oz0, ox1, oy1, oz1, any_open, dt,
                )
                entered = -1
                if k_lo <= k_hi and planes.shape[0] > 0:
                    k_lo, k_hi, t_lo, t_hi, entered = clip_planes(ox, oy, oz, dx, dy, dz, planes, dt, t_lo, t_hi,
                                                                  k_lo, k_hi)
                k_next = k_lo
                if capping and k_lo <= k_hi and a < ert:
                    face, gx, gy, gz = entry_face(ox, oy, oz, dx, dy, dz, cx0, cy0, cz0, cx1, cy1, cz1,
                                                  cut_lo, cut_hi, planes, entered, t_lo)
                    if face:
                        r, g, b, a, nne = cap_sample(
                            sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
                            wdx, wdy, wdz, inv_spacing, dt, k_lo, gx, gy, gz, r, g, b, a, cap,
                        )
                        n_samples += 1
                        n_nonempty += nne
                        k_next = k_lo + 1
                if k_next <= k_hi and a < ert:
                    state = start_ray(record, scratch, ray, t_lo, t_hi)
                    seg_open = False
                    seg_t0 = 0.0
                    seg_t1 = -math.inf
                    while True:
                        t0, t1, state = next_interval(record, scratch, ray, state,
                                                      seg_t1 if seg_open else -math.inf)
                        more = t0 <= t1
                        # What to composite now: [s0, s1] (one call site).
                        go = False
                        s0 = 0.0
                        s1 = 0.0
                        if merge:
                            if more and seg_open and t0 <= seg_t1:
                                # A touching interval extends the open segment.
                                if t1 > seg_t1:
                                    seg_t1 = t1
                                continue
                            if seg_open:
                                go = True
                                s0 = seg_t0
                                s1 = seg_t1
                            seg_open = more
                            seg_t0 = t0
                            seg_t1 = t1
                        elif more:
                            s0 = max(t0, t_lo)
                            s1 = min(t1, t_hi)
                            go = s0 <= s1
                        if go:
                            r, g, b, a, k_next, ns, nne = integrate(
                                record, scratch, state, mode, sampler, flat, nx, ny, nz, table, v_lo, scale, inv_spacing,
                                dt, ert, shading, ray, (wdx, wdy, wdz), s0, s1, k_next, k_lo, k_hi, (r, g, b, a),
                            )
                            n_samples += ns
                            n_nonempty += nne
                            if a >= ert:
                                break
                        if not more:
                            break
                write_pixel(out_rgba, py, px, r, g, b, a, background)
                out_samples[py, px] = n_samples
                out_nonempty[py, px] = n_nonempty



@njit(cache=True)
def new_scratch(record):
    """The record's traversal scratch (:func:`sparsecast.index.interval.make_scratch`)."""
    return make_scratch(record)


# The same driver without the on-disk cache, for records defined outside this
# package (a user's or a test's own index). Numba's cache index for a function
# pickles every signature it holds, so one record class that a later process
# cannot import would make every later cache load of ``dvr_tiles`` fail.
dvr_tiles_uncached = njit(nogil=True, error_model="numpy", **NO_REFCOUNT)(dvr_tiles.py_func)
_new_scratch_uncached = njit(new_scratch.py_func)


def render_chunk(first, last, record, data, frame, init, out_rgba, out_samples, out_nonempty) -> None:
    """:func:`dvr_tiles` with a fresh scratch: the kernel :func:`tiles_kernel` gives for the
    package's own records (a thread calls it per piece of tiles; the GIL is held only to
    allocate the scratch)."""
    dvr_tiles(first, last, record, new_scratch(record), data, frame, init, out_rgba, out_samples, out_nonempty)


def render_chunk_uncached(first, last, record, data, frame, init, out_rgba, out_samples, out_nonempty) -> None:
    """:func:`render_chunk` without the on-disk cache (records from outside the package)."""
    dvr_tiles_uncached(first, last, record, _new_scratch_uncached(record), data, frame, init, out_rgba,
                       out_samples, out_nonempty)


def tiles_kernel(record):
    """:func:`render_chunk` for the package's own records, else :func:`render_chunk_uncached`."""
    return render_chunk if _own(record) else render_chunk_uncached


def _own(value) -> bool:
    """Whether ``value`` and every record nested in it are classes of this package."""
    if isinstance(value, tuple) and hasattr(value, "_fields"):
        return type(value).__module__.startswith("sparsecast.") and all(_own(v) for v in value)
    return True
