"""Closest-hit traversal of the 4-wide triangle BVH (layout: :mod:`._wide_build_kernels`).

Per wide node the ray meets all four child boxes at once in float32 SIMD lanes
(:func:`..kernels.simd.slab4`; the near and far planes per axis picked once per
ray from the signs of its direction, so there is no min/max of plane pairs); the
children it enters go on the stack sorted by entry distance and the nearest is
entered at once, and a popped entry farther than the best hit so far is
dropped. Leaves test packets of four triangles in float64 SIMD lanes
(:func:`..kernels.simd.woop4`); the barycentrics and the shading normal are
computed once, for the winner.

**Watertight triangle test** (Woop, Benthin & Wald, JCGT 2013): the vertices are
translated to the ray origin and sheared so that the ray runs along +z; the
three 2-D edge functions of a shared edge are then computed from the same
numbers in opposite order, so they are exact negatives, and a ray through an
edge or vertex of a closed mesh finds one of its triangles (no cracks); edge
functions are in float64 (the float32 vertices' products are exact enough that
no double-precision fallback is needed).

**Conservative float32 box test** (Ize 2013): the ray is float64, the boxes
float32. Each plane gets its own float32 origin, rounded so that entries can
only come out earlier and exits later (:func:`slab_origins32`), the far planes'
inverses are widened by :data:`ROBUST32` (16 unit roundoffs, over the 7 that the
roundings cost), and the bound against the best hit is rounded up: rounding never drops a
box the ray touches. A ray with a zero direction component that runs in a box's
face plane counts as inside the slab (:func:`slab_origins`, :func:`slab_origins32`).

**Root pre-test** (:func:`misses_root`): before any of that set-up (six divisions,
twelve directed roundings, the shear) a ray meets the root box, widened, in
float64; one that misses it meets nothing and returns at once. Rays that miss the
scene are most of a frame's pixels wherever the mesh does not fill the view:
such a ray cost 84 ns of CPU with the set-up and the root node's test, 16 ns with
the pre-test (the cast loop alone: 9.5 ns; 262 k rays leaving the bunny's box, 2
threads, AMD EPYC Zen 3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels.borrow import NO_REFCOUNT
from ..kernels.camera import primary_ray
from ..kernels.parallel import run_chunks
from ..kernels.simd import slab4, woop4
from ..kernels.tiles import tile_bounds, tile_count
from ._wide_build_kernels import LEAF_SHIFT

#: rays per parallel work item of the batch driver
RAY_CHUNK = 64
#: far-plane widening of the float32 box test: 16 float32 unit roundoffs (2^-24), over
#: the 7 that the roundings of 1 / d, its widening, plane - o and the products cost
ROBUST32 = 1.0 + 2.0 ** -20
#: direction components below this (of a unit vector) count as zero
D_FLUSH = 2.0 ** -60


#: widening of the root box for :func:`misses_root`, relative to the scene's size and
#: coordinates (far above float64 rounding; float32 boxes hold their triangles already)
ROOT_PAD = 1e-6
#: per ray, the root box is widened by this much of the origin's largest coordinate too:
#: ``(plane - o) * inv`` rounds by about 1e-16 of ``|o|``
ORIGIN_PAD = 1e-13


def root_slab(root: np.ndarray) -> np.ndarray:
    """The root box ``(2, 3)`` (min, max corners) widened for :func:`misses_root`:
    (6,) float64 ``x0, y0, z0, x1, y1, z1``; an empty box (no primitive) stays empty."""
    lo, hi = np.asarray(root, np.float64)
    if not np.all(lo <= hi):
        return np.array([np.inf] * 3 + [-np.inf] * 3)
    pad = ROOT_PAD * float(np.max(hi - lo) + np.max(np.maximum(np.abs(lo), np.abs(hi)))) + 1e-300
    return np.concatenate([lo - pad, hi + pad])


# The float64 slab of kernels.ray.clip_box, inlined: clip_box (and the inverse it
# calls) are plain calls, and through them a ray beside the mesh cost 43 ns of CPU
# instead of 16 (bunny, 262 k rays, 2 threads).
@njit(cache=True, inline="always")
def _root_axis(o, d, lo, hi, tn, tf):
    """:func:`misses_root` along one axis: ``[tn, tf]`` cut to the slab ``[lo, hi]``."""
    if d == 0.0:
        if o < lo or o > hi:
            return math.inf, -math.inf
        return tn, tf
    a = (lo - o) / d
    b = (hi - o) / d
    return max(tn, min(a, b)), min(tf, max(a, b))


@njit(cache=True, inline="always")
def misses_root(root, ox, oy, oz, dx, dy, dz, t_min, t_max):
    """Whether the ray misses the root box :func:`root_slab` within ``[t_min, t_max]``:
    then it meets no primitive. Direction components under :data:`D_FLUSH` count as
    zero, as in the box tests of the traversal."""
    pad = ORIGIN_PAD * max(abs(ox), abs(oy), abs(oz))
    tn, tf = _root_axis(ox, 0.0 if abs(dx) < D_FLUSH else dx, root[0] - pad, root[3] + pad, t_min, t_max)
    tn, tf = _root_axis(oy, 0.0 if abs(dy) < D_FLUSH else dy, root[1] - pad, root[4] + pad, tn, tf)
    tn, tf = _root_axis(oz, 0.0 if abs(dz) < D_FLUSH else dz, root[2] - pad, root[5] + pad, tn, tf)
    return not tn <= tf


def stack_size(depth: int) -> int:
    """Stack entries a ray needs in a wide tree of ``depth`` levels (up to three siblings wait per level)."""
    return 3 * int(depth) + 4


@njit(cache=True, inline="always")
def _inv(d):
    # A huge finite inverse keeps (plane - o) * inv free of 0 * inf = NaN.
    if d == 0.0:
        return 1e30
    return 1.0 / d


@njit(cache=True, inline="always")
def slab_origins(o, d):
    """Origin coordinate for the near and the far plane of a slab test along one axis.

    With ``d = 0`` the slab test multiplies by a huge inverse, and a ray running in
    a plane of the slab (``o`` equal to a box's min or max) would give ``0 * 1e30 =
    0``: the box would end at ``t = 0``. Moving the origin a few ulps into the slab
    for each plane (up for the near one, down for the far one) makes such a ray
    inside, as the triangle test sees it; other rays keep their origin.
    """
    if d != 0.0:
        return o, o
    eps = max(abs(o) * 2.0 ** -50, 1e-300)
    return o + eps, o - eps


@njit(cache=True, inline="always")
def _step32(f, s):
    """Float32 ``f`` moved by two to four float32 ulps in the direction of ``s = +-1``.

    Arithmetic instead of ``np.nextafter``, which compiles to a libm call (with
    the vector registers spilled around it) per coordinate per ray: ``2^-22 |f|``
    is two to four ulps, ``1e-38`` moves a zero; going further than the next
    float32 only makes the box test a little more conservative.
    """
    return np.float32(f + s * (abs(f) * 2.0 ** -22 + 1e-38))


@njit(cache=True, inline="always")
def _f32(x, up):
    """``x`` as a float32 not below it (``up``) or not above it."""
    f = np.float32(x)
    if up:
        if f < x:
            f = _step32(f, 1.0)
    elif f > x:
        f = _step32(f, -1.0)
    return f


@njit(cache=True, inline="always")
def slab_origins32(o, d):
    """Float32 origin coordinates for the near and the far plane of a float32 slab test.

    The box test runs in float32 while the ray is float64, so the origin is rounded
    *towards safety*: for the near plane in the direction of ``d`` (the entry
    distance can only come out smaller), for the far plane against it (the exit
    only larger). With ``d = 0`` both move strictly into the slab, the float32 form
    of :func:`slab_origins`: a ray running in a face plane is inside.
    """
    if d > 0.0:
        return _f32(o, True), _f32(o, False)
    if d < 0.0:
        return _f32(o, False), _f32(o, True)
    f = np.float32(o)
    near = f if f > o else _step32(f, 1.0)
    far = f if f < o else _step32(f, -1.0)
    return near, far


@njit(cache=True, inline="always")
def slab_setup32_flat(ox, oy, oz, dx, dy, dz):
    """A ray's ``rows + org + inv`` for :func:`..kernels.simd.slab4` on 4-wide SoA nodes
    (box row ``r`` at ``4 r``) as one flat 18-tuple, the conservative float32 test of
    the module docstring; callers group it into the three 6-tuples ``slab4`` takes.

    Flat because it is inlined into the drivers' chunk kernels, once per ray (as a
    call it was 9 % of the samples of an RBVH frame, dragons-7m: the call and the
    reload of its returned tuple; inlined, the frame is 3-4 % faster), and because
    Numba's array analysis failed on an inlined function returning nested tuples when
    the drivers were ``prange`` loops.

    ``d`` must have its components under :data:`D_FLUSH` flushed to zero (a float32
    inverse of them would overflow).
    """
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    # Near / far rows of the boxes per axis (offsets into a node), from the direction's signs.
    nxr, fxr = (0, 12) if ix >= 0.0 else (12, 0)
    nyr, fyr = (4, 16) if iy >= 0.0 else (16, 4)
    nzr, fzr = (8, 20) if iz >= 0.0 else (20, 8)
    onx, ofx = slab_origins32(ox, dx)
    ony, ofy = slab_origins32(oy, dy)
    onz, ofz = slab_origins32(oz, dz)
    # Far planes scaled by ROBUST32, so that the float32 rounding of 1 / d, of the
    # subtraction and of the product never puts the exit before the entry (Ize 2013).
    return (nxr, nyr, nzr, fxr, fyr, fzr, onx, ony, onz, ofx, ofy, ofz,
            np.float32(ix), np.float32(iy), np.float32(iz),
            np.float32(ix * ROBUST32), np.float32(iy * ROBUST32), np.float32(iz * ROBUST32))


@njit(cache=True, inline="always")
def _cull(best):
    """Float32 bound of the entry distances still worth visiting when the best hit is at ``best``."""
    return _f32(best * ROBUST32, True)


@njit(cache=True)
def vertex_normal(faces, vnormals, face, a, b):
    """Unit shading normal of face ``face`` at barycentrics ``a, b`` of its vertices 1 and 2
    (the vertex normals interpolated; zero where they cancel). Shared by every layout."""
    w = 1.0 - a - b
    f0, f1, f2 = faces[face, 0], faces[face, 1], faces[face, 2]
    nx = w * vnormals[f0, 0] + a * vnormals[f1, 0] + b * vnormals[f2, 0]
    ny = w * vnormals[f0, 1] + a * vnormals[f1, 1] + b * vnormals[f2, 1]
    nz = w * vnormals[f0, 2] + a * vnormals[f1, 2] + b * vnormals[f2, 2]
    ln = math.sqrt(nx * nx + ny * ny + nz * nz)
    if ln > 0.0:
        nx, ny, nz = nx / ln, ny / ln, nz / ln
    return nx, ny, nz


@njit(cache=True, inline="always")
def closest_hit_wide(box, child, tri4, face4, faces, vnormals, root, ox, oy, oz, dx, dy, dz, t_min, t_max,
                     st_node, st_t, lane_b, lane_t):
    """Nearest triangle hit in ``[t_min, t_max]``.

    ``box`` and ``child`` are the nodes (n, 32) as float32 and as int32
    (:attr:`.wide.WideBVH.nodes`): boxes at ``4 row + c``, children at ``24 + c``.
    ``root`` is :func:`root_slab` of the tree's root box. Scratch: ``st_node`` (s,)
    int32, ``st_t`` (s,) float32, ``lane_b`` (4,) float32, ``lane_t`` (8,) float64.

    Returns ``(t, nx, ny, nz, face, -1, a, b)`` as :func:`._bvh_kernels.closest_hit`
    (``t = inf`` on a miss; unit shading normal; barycentrics ``a, b`` of
    vertices 1 and 2).
    """
    if misses_root(root, ox, oy, oz, dx, dy, dz, t_min, t_max):
        return math.inf, 0.0, 0.0, 0.0, -1, -1, 0.0, 0.0
    # A component below 2^-60 of a unit vector is under the rounding of the others:
    # zero makes the ray exactly axis-parallel for both tests and keeps 1/d finite in float32.
    if abs(dx) < D_FLUSH:
        dx = 0.0
    if abs(dy) < D_FLUSH:
        dy = 0.0
    if abs(dz) < D_FLUSH:
        dz = 0.0
    (nxr, nyr, nzr, fxr, fyr, fzr, onx, ony, onz, ofx, ofy, ofz,
     ix3, iy3, iz3, fx3, fy3, fz3) = slab_setup32_flat(ox, oy, oz, dx, dy, dz)
    rows = (nxr, nyr, nzr, fxr, fyr, fzr)
    org = (onx, ony, onz, ofx, ofy, ofz)
    inv = (ix3, iy3, iz3, fx3, fy3, fz3)
    t_lo = _f32(t_min, False)
    # Watertight test set-up: kz the dominant axis, shear onto it.
    ax_, ay_, az_ = abs(dx), abs(dy), abs(dz)
    if ax_ >= ay_ and ax_ >= az_:
        kz = 0
    elif ay_ >= az_:
        kz = 1
    else:
        kz = 2
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    d_k = (dx, dy, dz)
    o_k = (ox, oy, oz)
    dkz = d_k[kz]
    sx, sy, sz = d_k[kx] / dkz, d_k[ky] / dkz, 1.0 / dkz
    okx, oky, okz = o_k[kx], o_k[ky], o_k[kz]
    axes, org_k, shear = (kx, ky, kz), (okx, oky, okz), (sx, sy, sz)
    best = t_max
    hi = _cull(best)
    best_p = -1
    best_lane = 0
    best_det = 0.0
    sp = 0
    node = 0
    while True:
        if node >= 0:
            mask = slab4(box, node, rows, org, inv, t_lo, hi, lane_b)
            if mask != 0:
                # Entered children onto the stack in decreasing entry distance, then
                # straight into the nearest (it was just tested against the best hit).
                sp0 = sp
                for c in range(4):
                    if mask & (1 << c):
                        t = lane_b[c]
                        j = sp
                        while j > sp0 and st_t[j - 1] < t:
                            st_node[j] = st_node[j - 1]
                            st_t[j] = st_t[j - 1]
                            j -= 1
                        st_node[j] = child[node, 24 + c]
                        st_t[j] = t
                        sp += 1
                sp -= 1
                node = st_node[sp]
                continue
        else:
            code = -1 - node
            p0 = code >> LEAF_SHIFT
            for p in range(p0, p0 + (code & ((1 << LEAF_SHIFT) - 1)) + 1):
                if woop4(tri4, p, axes, org_k, shear, t_min, best, lane_t):
                    for lane in range(4):
                        t = lane_t[lane]
                        if t < best:
                            best = t
                            best_p, best_lane, best_det = p, lane, lane_t[4 + lane]
            hi = _cull(best)
        # Pop the nearest waiting child that can still hold a closer hit.
        while sp > 0:
            sp -= 1
            if st_t[sp] <= hi:
                break
        else:
            break
        node = st_node[sp]
    if best_p < 0:
        return math.inf, 0.0, 0.0, 0.0, -1, -1, 0.0, 0.0
    # Barycentrics of vertices 1 and 2 (their edge functions over det), once for the winner.
    p, lane = best_p, best_lane
    vax = tri4[p, kx, lane] - okx
    vay = tri4[p, ky, lane] - oky
    vaz = tri4[p, kz, lane] - okz
    vbx = tri4[p, 3 + kx, lane] - okx
    vby = tri4[p, 3 + ky, lane] - oky
    vbz = tri4[p, 3 + kz, lane] - okz
    vcx = tri4[p, 6 + kx, lane] - okx
    vcy = tri4[p, 6 + ky, lane] - oky
    vcz = tri4[p, 6 + kz, lane] - okz
    a_x, a_y = vax - sx * vaz, vay - sy * vaz
    b_x, b_y = vbx - sx * vbz, vby - sy * vbz
    c_x, c_y = vcx - sx * vcz, vcy - sy * vcz
    ha = (a_x * c_y - a_y * c_x) / best_det
    hb = (b_x * a_y - b_y * a_x) / best_det
    face = face4[p, lane]
    nx, ny, nz = vertex_normal(faces, vnormals, face, ha, hb)
    return best, nx, ny, nz, face, -1, ha, hb


# The drivers below spread pieces of chunks of rays (or of pixel tiles) over threads
# (kernels.parallel.run_chunks); a chunk or a tile is traced by a plain kernel with the
# traversal inlined into it. Inlined into a prange body instead, the traversal went
# through Numba's parfor passes and the parallel gufunc's compile with it: 20-26 s a
# driver cold; a prange loop of one call per chunk took 11-12 s; without prange, the
# parfor's 2-3 s go too (one call per 64 rays costs nothing measurable).
@njit(cache=True, **NO_REFCOUNT)
def _rays_chunk(box, child, tri4, face4, faces, vnormals, root, origins, dirs, t_min, t_max, r0, r1,
                st_node, st_t, lane_b, lane_t, out_t, out_n, out_face, out_tile, out_uv):
    """Closest hits of rays ``r0..r1-1`` (:func:`cast_rays_wide`), :func:`closest_hit_wide` inlined;
    compiled without reference counting (the caller holds every array)."""
    for r in range(r0, r1):
        t, nx, ny, nz, f, tl, a, b = closest_hit_wide(
            box, child, tri4, face4, faces, vnormals, root, origins[r, 0], origins[r, 1], origins[r, 2],
            dirs[r, 0], dirs[r, 1], dirs[r, 2], t_min, t_max, st_node, st_t, lane_b, lane_t)
        out_t[r] = t
        out_n[r, 0], out_n[r, 1], out_n[r, 2] = nx, ny, nz
        out_face[r], out_tile[r] = f, tl
        out_uv[r, 0], out_uv[r, 1] = a, b


@njit(cache=True, **NO_REFCOUNT)
def _primary_tile(box, child, tri4, face4, faces, vnormals, root, params, width, height, tile,
                  st_node, st_t, lane_b, lane_t, out_t, out_n, out_face, out_tile, out_uv):
    """Closest hits of the primary rays of pixel tile ``tile`` (:func:`cast_primary_wide`)."""
    x0, x1, y0, y1 = tile_bounds(tile, width, height)
    for py in range(y0, y1):
        for px in range(x0, x1):
            ox, oy, oz, dx, dy, dz = primary_ray(params, px, py, width, height)
            t, nx, ny, nz, f, tl, a, b = closest_hit_wide(
                box, child, tri4, face4, faces, vnormals, root, ox, oy, oz, dx, dy, dz, 0.0, np.inf,
                st_node, st_t, lane_b, lane_t)
            out_t[py, px] = t
            out_n[py, px, 0], out_n[py, px, 1], out_n[py, px, 2] = nx, ny, nz
            out_face[py, px], out_tile[py, px] = f, tl
            out_uv[py, px, 0], out_uv[py, px, 1] = a, b


def cast_rays_wide(box, child, tri4, face4, faces, vnormals, root, origins, dirs, t_min, t_max, n_stack,
                   out_t, out_n, out_face, out_tile, out_uv) -> None:
    """Closest hits of a batch of rays (unit directions), in chunks of :data:`RAY_CHUNK`
    spread over threads (:func:`~sparsecast.kernels.parallel.run_chunks`)."""
    run_chunks(_ray_chunks, -(-origins.shape[0] // RAY_CHUNK), None, box, child, tri4, face4, faces, vnormals,
               root, origins, dirs, t_min, t_max, n_stack, out_t, out_n, out_face, out_tile, out_uv)


@njit(cache=True, nogil=True)
def _ray_chunks(first, last, box, child, tri4, face4, faces, vnormals, root, origins, dirs, t_min, t_max,
                n_stack, out_t, out_n, out_face, out_tile, out_uv):
    """Chunks ``first .. last - 1`` of :func:`cast_rays_wide`, with one traversal stack."""
    n = origins.shape[0]
    st_node, st_t = np.empty(n_stack, np.int32), np.empty(n_stack, np.float32)
    lane_b, lane_t = np.empty(4, np.float32), np.empty(8)
    for c in range(first, last):
        _rays_chunk(box, child, tri4, face4, faces, vnormals, root, origins, dirs, t_min, t_max,
                    c * RAY_CHUNK, min(n, (c + 1) * RAY_CHUNK), st_node, st_t, lane_b, lane_t,
                    out_t, out_n, out_face, out_tile, out_uv)


def cast_primary_wide(box, child, tri4, face4, faces, vnormals, root, params, width, height, n_stack,
                      out_t, out_n, out_face, out_tile, out_uv) -> None:
    """Closest hits of the camera's primary rays, pixel tiles spread over threads (outputs
    as :func:`._bvh_kernels.cast_primary`)."""
    run_chunks(_primary_tiles, int(tile_count(width, height)), None, box, child, tri4, face4, faces, vnormals,
               root, params, width, height, n_stack, out_t, out_n, out_face, out_tile, out_uv)


@njit(cache=True, nogil=True)
def _primary_tiles(first, last, box, child, tri4, face4, faces, vnormals, root, params, width, height, n_stack,
                   out_t, out_n, out_face, out_tile, out_uv):
    """Pixel tiles ``first .. last - 1`` of :func:`cast_primary_wide`, with one traversal stack."""
    st_node, st_t = np.empty(n_stack, np.int32), np.empty(n_stack, np.float32)
    lane_b, lane_t = np.empty(4, np.float32), np.empty(8)
    for tile in range(first, last):
        _primary_tile(box, child, tri4, face4, faces, vnormals, root, params, width, height, tile,
                      st_node, st_t, lane_b, lane_t, out_t, out_n, out_face, out_tile, out_uv)
