"""Closest-hit traversal of the 4-wide RBVH (layout: :mod:`._rbvh_wide_build_kernels`).

Inner nodes as in the exact wide BVH (:mod:`._wide_kernels`): the four child
boxes of a node are met at once in float32 SIMD lanes (:func:`..kernels.simd.slab4`,
the conservative test: rounding never drops a box the ray touches), near and far
planes picked once per ray from the direction's signs; the children the ray
enters go on the stack sorted by entry distance, nearest on top, and an entry
farther than the best hit so far (rounded up) is dropped when popped.

Leaves go on the same stack as ``-1 - (WIDTH node + slot)``, so a leaf is opened in
order of its box's entry distance like any child; a tile's mip level is picked
from the float64 entry distance into its box, as the binary kernel does. Leaf
tests are the binary kernel's: the height-field search of
:func:`._rbvh_kernels.tile_hit` and the two-sided Möller–Trumbore test of
:func:`._bvh_kernels.intersect_triangle`, so both layouts find the same hits.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels.borrow import NO_REFCOUNT
from ..kernels.camera import primary_ray
from ..kernels.parallel import run_chunks
from ..kernels.tiles import tile_bounds, tile_count
from ._bvh_kernels import TILE_LEAF, hit_normal, intersect_triangle, mip_tile
from ._rbvh_wide_build_kernels import WIDTH
from ._rbvh_kernels import tile_hit
from ..kernels.simd import slab4
from ._wide_kernels import D_FLUSH, _cull, _f32, _inv, misses_root, slab_origins, slab_setup32_flat

# slab4 tests exactly four boxes a node (<4 x float>)
if WIDTH != 4:  # pragma: no cover - a guard for whoever changes WIDTH
    raise ImportError(f"the 4-wide RBVH kernels need WIDTH == 4, got {WIDTH}")

#: rays per parallel work item of the batch driver
RAY_CHUNK = 64


def stack_size(depth: int) -> int:
    """Stack entries a ray needs in a wide tree of ``depth`` levels (``WIDTH - 1`` siblings wait
    per level, and the deepest node's children may all be leaves)."""
    return (WIDTH - 1) * int(depth) + WIDTH + 1


@njit(cache=True, inline="always")
def _leaf_entry(box, node, c, rows, org, inv, t_min):
    """Float64 entry distance of the ray into box ``c`` of ``node`` (its near planes only).

    Picks a tile's mip level: the float32 lanes of :func:`.slab4` order and cull the
    boxes, but rounded entries would move the level's thresholds, and both layouts
    choose the same level from the same float64 distance.
    """
    nxr, nyr, nzr = rows
    onx, ony, onz = org
    ix, iy, iz = inv
    return max(max((box[node, nxr + c] - onx) * ix, (box[node, nyr + c] - ony) * iy),
               max((box[node, nzr + c] - onz) * iz, t_min))


@njit(cache=True, inline="always")
def closest_hit_rbvh_wide(box, child, tris, tri_face, faces, vnormals, tiles, tiles_i,
                          atlas_depth, atlas_normal, root, ox, oy, oz, dx, dy, dz, t_min, t_max,
                          st_node, st_t, lane_b, fp0, spread, n_levels):
    """Nearest hit in ``[t_min, t_max]``; scratch ``st_node`` (s,) int32, ``st_t`` (s,) float64 and
    ``lane_b`` (WIDTH,) float32.

    ``box`` and ``child`` are the nodes (n, 32) as float32 and as int32
    (:attr:`.rbvh_wide.WideRBVH.nodes`). Returns ``(t, nx, ny, nz, face, tile, a, b)``
    as :func:`._bvh_kernels.closest_hit`. ``root`` is :func:`._wide_kernels.root_slab` of the
    tree's root box: a ray that misses it returns before any set-up.
    """
    if misses_root(root, ox, oy, oz, dx, dy, dz, t_min, t_max):
        return math.inf, 0.0, 0.0, 0.0, -1, -1, 0.0, 0.0
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    # The box test is the exact wide BVH's conservative float32 one (see
    # ._wide_kernels): tiny direction components flushed to zero for it alone (the
    # leaf tests keep the ray), origins rounded towards safety, far planes widened.
    bdx = 0.0 if abs(dx) < D_FLUSH else dx
    bdy = 0.0 if abs(dy) < D_FLUSH else dy
    bdz = 0.0 if abs(dz) < D_FLUSH else dz
    (nxr, nyr, nzr, fxr, fyr, fzr, onx, ony, onz, ofx, ofy, ofz,
     ix3, iy3, iz3, fx3, fy3, fz3) = slab_setup32_flat(ox, oy, oz, bdx, bdy, bdz)
    rows = (nxr, nyr, nzr, fxr, fyr, fzr)
    org = (onx, ony, onz, ofx, ofy, ofz)
    inv = (ix3, iy3, iz3, fx3, fy3, fz3)
    t_lo = _f32(t_min, False)
    # The float64 near planes of the mip level's entry distance (_leaf_entry).
    rows64 = (0 if ix >= 0.0 else 12, 4 if iy >= 0.0 else 16, 8 if iz >= 0.0 else 20)
    org64 = (slab_origins(ox, dx)[0], slab_origins(oy, dy)[0], slab_origins(oz, dz)[0])
    inv64 = (ix, iy, iz)
    n_tiles = tiles.shape[0] // n_levels
    best = t_max
    hi = _cull(best)
    face = -1
    best_k = -1
    tile = -1
    ha = hb = 0.0
    sp = 1
    st_node[0] = 0
    st_t[0] = t_lo
    while sp > 0:
        sp -= 1
        if st_t[sp] > hi:
            continue
        entry = st_node[sp]
        if entry >= 0:
            node = entry
            mask = slab4(box, node, rows, org, inv, t_lo, hi, lane_b)
            sp0 = sp
            for c in range(WIDTH):
                if not mask & (1 << c):
                    continue
                t = lane_b[c]
                code = child[node, 6 * WIDTH + c] if child[node, 7 * WIDTH + c] == 0 else -1 - (WIDTH * node + c)
                # Insert keeping entries sp0..sp in decreasing distance: nearest on top.
                j = sp
                while j > sp0 and st_t[j - 1] < t:
                    st_node[j] = st_node[j - 1]
                    st_t[j] = st_t[j - 1]
                    j -= 1
                st_node[j] = code
                st_t[j] = t
                sp += 1
            continue
        slot = -1 - entry
        node, c = slot // WIDTH, slot % WIDTH
        first = child[node, 6 * WIDTH + c]
        count = child[node, 7 * WIDTH + c]
        if count > 0:
            for k in range(first, first + count):
                t, u, v = intersect_triangle(tris, k, ox, oy, oz, dx, dy, dz, t_min, best)
                if t < best:
                    best, face, best_k, tile, ha, hb = t, tri_face[k], k, -1, u, v
        elif count == TILE_LEAF:
            k = first
            if n_levels > 1:
                t_entry = _leaf_entry(box, node, c, rows64, org64, inv64, t_min)
                k = mip_tile(k, t_entry, fp0, spread, n_levels, tiles, n_tiles)
            t, s, u = tile_hit(k, ox, oy, oz, dx, dy, dz, t_min, best, tiles, tiles_i, atlas_depth)
            if t < best:
                best, face, best_k, tile, ha, hb = t, -1, -1, k, s, u
        hi = _cull(best)
    if face < 0 and tile < 0:
        return math.inf, 0.0, 0.0, 0.0, -1, -1, 0.0, 0.0
    nx, ny, nz = hit_normal(faces, vnormals, tiles_i, atlas_normal, best_k, tile, ha, hb)
    return best, nx, ny, nz, face, tile, ha, hb


# Chunk and tile kernels with the traversal inlined, which the drivers below spread over
# threads (see ._wide_kernels: parfor passes over an inlined traversal took most of these
# drivers' 34-37 s cold compiles when they were prange loops).
@njit(cache=True, **NO_REFCOUNT)
def _rays_chunk(box, child, tris, tri_face, faces, vnormals, tiles, tiles_i, atlas_depth, atlas_normal, root,
                origins, dirs, t_min, t_max, r0, r1, st_node, st_t, lane_b, fp0, spread, n_levels,
                out_t, out_n, out_face, out_tile, out_uv):
    """Closest hits of rays ``r0..r1-1`` (:func:`cast_rays_rbvh_wide`)."""
    for r in range(r0, r1):
        t, nx, ny, nz, f, tl, a, b = closest_hit_rbvh_wide(
            box, child, tris, tri_face, faces, vnormals, tiles, tiles_i, atlas_depth, atlas_normal, root,
            origins[r, 0], origins[r, 1], origins[r, 2], dirs[r, 0], dirs[r, 1], dirs[r, 2], t_min, t_max,
            st_node, st_t, lane_b, fp0, spread, n_levels)
        out_t[r] = t
        out_n[r, 0], out_n[r, 1], out_n[r, 2] = nx, ny, nz
        out_face[r], out_tile[r] = f, tl
        out_uv[r, 0], out_uv[r, 1] = a, b


@njit(cache=True, **NO_REFCOUNT)
def _primary_tile(box, child, tris, tri_face, faces, vnormals, tiles, tiles_i, atlas_depth, atlas_normal, root,
                  params, width, height, tile, st_node, st_t, lane_b, fp0, spread, n_levels,
                  out_t, out_n, out_face, out_tile, out_uv):
    """Closest hits of the primary rays of pixel tile ``tile`` (:func:`cast_primary_rbvh_wide`)."""
    x0, x1, y0, y1 = tile_bounds(tile, width, height)
    for py in range(y0, y1):
        for px in range(x0, x1):
            ox, oy, oz, dx, dy, dz = primary_ray(params, px, py, width, height)
            t, nx, ny, nz, f, tl, a, b = closest_hit_rbvh_wide(
                box, child, tris, tri_face, faces, vnormals, tiles, tiles_i, atlas_depth, atlas_normal, root,
                ox, oy, oz, dx, dy, dz, 0.0, np.inf, st_node, st_t, lane_b, fp0, spread, n_levels)
            out_t[py, px] = t
            out_n[py, px, 0], out_n[py, px, 1], out_n[py, px, 2] = nx, ny, nz
            out_face[py, px], out_tile[py, px] = f, tl
            out_uv[py, px, 0], out_uv[py, px, 1] = a, b


def cast_rays_rbvh_wide(box, child, tris, tri_face, faces, vnormals, tiles, tiles_i,
                        atlas_depth, atlas_normal, root, origins, dirs, t_min, t_max, n_stack, fp0, spread,
                        n_levels, out_t, out_n, out_face, out_tile, out_uv) -> None:
    """Closest hits of a batch of rays (unit directions), in chunks of :data:`RAY_CHUNK`
    spread over threads (:func:`~sparsecast.kernels.parallel.run_chunks`).

    ``fp0 + spread * t`` is the rays' footprint for mip selection (0, 0: finest).
    """
    run_chunks(_ray_chunks, -(-origins.shape[0] // RAY_CHUNK), None, box, child, tris, tri_face, faces, vnormals,
               tiles, tiles_i, atlas_depth, atlas_normal, root, origins, dirs, t_min, t_max, n_stack, fp0, spread,
               n_levels, out_t, out_n, out_face, out_tile, out_uv)


@njit(cache=True, nogil=True)
def _ray_chunks(first, last, box, child, tris, tri_face, faces, vnormals, tiles, tiles_i, atlas_depth,
                atlas_normal, root, origins, dirs, t_min, t_max, n_stack, fp0, spread, n_levels,
                out_t, out_n, out_face, out_tile, out_uv):
    """Chunks ``first .. last - 1`` of :func:`cast_rays_rbvh_wide`, with one traversal stack."""
    n = origins.shape[0]
    st_node, st_t, lane_b = np.empty(n_stack, np.int32), np.empty(n_stack), np.empty(WIDTH, np.float32)
    for c in range(first, last):
        _rays_chunk(box, child, tris, tri_face, faces, vnormals, tiles, tiles_i, atlas_depth, atlas_normal, root,
                    origins, dirs, t_min, t_max, c * RAY_CHUNK, min(n, (c + 1) * RAY_CHUNK),
                    st_node, st_t, lane_b, fp0, spread, n_levels, out_t, out_n, out_face, out_tile, out_uv)


def cast_primary_rbvh_wide(box, child, tris, tri_face, faces, vnormals, tiles, tiles_i,
                           atlas_depth, atlas_normal, root, params, width, height, n_stack, n_levels,
                           out_t, out_n, out_face, out_tile, out_uv) -> None:
    """Closest hits of the camera's primary rays, pixel tiles spread over threads (outputs
    as :func:`._bvh_kernels.cast_primary`)."""
    # A pixel's footprint: its angle times the distance (perspective) or its fixed width (orthographic).
    pixel = 2.0 * math.sqrt(params[9] * params[9] + params[10] * params[10] + params[11] * params[11]) / height
    fp0 = 0.0 if params[12] != 0.0 else pixel
    spread = pixel if params[12] != 0.0 else 0.0
    run_chunks(_primary_tiles, int(tile_count(width, height)), None, box, child, tris, tri_face, faces, vnormals,
               tiles, tiles_i, atlas_depth, atlas_normal, root, params, width, height, n_stack, float(fp0),
               float(spread), n_levels, out_t, out_n, out_face, out_tile, out_uv)


@njit(cache=True, nogil=True)
def _primary_tiles(first, last, box, child, tris, tri_face, faces, vnormals, tiles, tiles_i, atlas_depth,
                   atlas_normal, root, params, width, height, n_stack, fp0, spread, n_levels,
                   out_t, out_n, out_face, out_tile, out_uv):
    """Pixel tiles ``first .. last - 1`` of :func:`cast_primary_rbvh_wide`, with one traversal stack."""
    st_node, st_t, lane_b = np.empty(n_stack, np.int32), np.empty(n_stack), np.empty(WIDTH, np.float32)
    for tile in range(first, last):
        _primary_tile(box, child, tris, tri_face, faces, vnormals, tiles, tiles_i, atlas_depth, atlas_normal, root,
                      params, width, height, tile, st_node, st_t, lane_b, fp0, spread, n_levels,
                      out_t, out_n, out_face, out_tile, out_uv)
