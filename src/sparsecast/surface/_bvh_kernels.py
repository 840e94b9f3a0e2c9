"""Closest-hit traversal of a surface BVH whose leaves are triangles or height-field tiles.

The exact triangle BVH is the special case with no tiles, and the hybrid RBVH
is the general one, so both run the same kernel and their speeds compare like
for like. Node layout (see :mod:`._bvh_build_kernels`): ``node_count > 0`` is a
triangle leaf of ``node_count`` triangles from ``node_child``; ``node_count == 0``
an inner node with children ``node_child`` and ``node_child + 1``;
``node_count == TILE_LEAF`` a tile leaf whose tile is ``node_child``;
``node_count <= -2`` a disc leaf of ``-1 - node_count`` discs from ``node_child``
(:func:`disc_leaf_code`). Leaf triangle ``k`` is ``tris[k]``, mesh face
``tri_face[k]``, with shading normals ``vnormals[faces[k]]`` (``faces`` is in leaf
order, so an index stores normals for its own triangles only). Leaf disc ``k`` is
``discs[k] = (cx, cy, cz, nx, ny, nz, r)``, point ``disc_point[k]`` of the cloud.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels.camera import primary_ray
from ..kernels.tiles import tile_bounds, tile_count
from ._rbvh_kernels import TILE_OFFSET, TILE_RES, tile_hit, tile_normal
from ._wide_kernels import _inv, slab_origins, vertex_normal  # one safe inverse, one shading normal for both layouts

#: ``node_count`` of a tile leaf
TILE_LEAF = -1
#: rays per parallel work item of the batch driver
RAY_CHUNK = 64


def disc_leaf_code(count):
    """``node_count`` of a leaf of ``count >= 1`` discs (-2, -3, ...; decoded as ``-1 - code``)."""
    return -1 - count


@njit(cache=True, inline="always")
def ray_box(nb, k, o, ix, iy, iz, t_min, t_max):
    """Entry distance of the ray into node box ``k``, or ``inf`` when it misses.

    ``o = (lox, loy, loz, hix, hiy, hiz)``: the origin for the boxes' min and max
    planes (:func:`._wide_kernels.slab_origins`: a ray in a face plane is inside).
    """
    a = (nb[k, 0, 0] - o[0]) * ix
    b = (nb[k, 1, 0] - o[3]) * ix
    tn, tf = min(a, b), max(a, b)
    a = (nb[k, 0, 1] - o[1]) * iy
    b = (nb[k, 1, 1] - o[4]) * iy
    tn, tf = max(tn, min(a, b)), min(tf, max(a, b))
    a = (nb[k, 0, 2] - o[2]) * iz
    b = (nb[k, 1, 2] - o[5]) * iz
    tn, tf = max(tn, min(a, b)), min(tf, max(a, b))
    tn = max(tn, t_min)
    if tn <= min(tf, t_max):
        return tn
    return math.inf


@njit(cache=True, inline="always")
def intersect_triangle(tris, k, ox, oy, oz, dx, dy, dz, t_min, t_max):
    """Möller–Trumbore, two-sided: ``(t, b1, b2)`` with ``t = inf`` on a miss."""
    ax, ay, az = tris[k, 0, 0], tris[k, 0, 1], tris[k, 0, 2]
    e1x, e1y, e1z = tris[k, 1, 0] - ax, tris[k, 1, 1] - ay, tris[k, 1, 2] - az
    e2x, e2y, e2z = tris[k, 2, 0] - ax, tris[k, 2, 1] - ay, tris[k, 2, 2] - az
    px, py, pz = dy * e2z - dz * e2y, dz * e2x - dx * e2z, dx * e2y - dy * e2x
    det = e1x * px + e1y * py + e1z * pz
    if det == 0.0:
        return math.inf, 0.0, 0.0
    inv = 1.0 / det
    tx, ty, tz = ox - ax, oy - ay, oz - az
    u = (tx * px + ty * py + tz * pz) * inv
    if u < 0.0 or u > 1.0:
        return math.inf, 0.0, 0.0
    qx, qy, qz = ty * e1z - tz * e1y, tz * e1x - tx * e1z, tx * e1y - ty * e1x
    v = (dx * qx + dy * qy + dz * qz) * inv
    if v < 0.0 or u + v > 1.0:
        return math.inf, 0.0, 0.0
    t = (e2x * qx + e2y * qy + e2z * qz) * inv
    if t < t_min or t > t_max:
        return math.inf, 0.0, 0.0
    return t, u, v


@njit(cache=True, inline="always")
def intersect_disc(discs, k, ox, oy, oz, dx, dy, dz, t_min, t_max):
    """Two-sided ray-disc test: the ray meets the disc's plane at ``t`` within radius ``r``
    of its centre; ``inf`` on a miss (a ray in the plane misses: the disc has no thickness)."""
    nx, ny, nz = discs[k, 3], discs[k, 4], discs[k, 5]
    den = dx * nx + dy * ny + dz * nz
    if den == 0.0:
        return math.inf
    cx, cy, cz = discs[k, 0], discs[k, 1], discs[k, 2]
    t = ((cx - ox) * nx + (cy - oy) * ny + (cz - oz) * nz) / den
    if t < t_min or t > t_max:
        return math.inf
    px, py, pz = ox + t * dx - cx, oy + t * dy - cy, oz + t * dz - cz
    r = discs[k, 6]
    if px * px + py * py + pz * pz > r * r:
        return math.inf
    return t


@njit(cache=True, inline="always")
def mip_tile(k, t_entry, fp0, spread, n_levels, tiles, n_tiles):
    """Tile of leaf ``k`` at the mip level whose texel is at least the ray footprint."""
    fp = fp0 + spread * max(t_entry, 0.0)
    u2 = tiles[k, 3] * tiles[k, 3] + tiles[k, 4] * tiles[k, 4] + tiles[k, 5] * tiles[k, 5]
    ratio = fp * math.sqrt(u2)  # footprint in level-0 texels
    level = 0
    while ratio >= 2.0 and level < n_levels - 1:
        ratio *= 0.5
        level += 1
    return k + level * n_tiles


@njit(cache=True)
def hit_normal(faces, vnormals, tiles_i, atlas_normal, leaf_tri, tile, a, b):
    """Unit shading normal of a hit on leaf triangle ``leaf_tri`` (barycentrics ``a, b`` of
    vertices 1 and 2) or, when ``leaf_tri < 0``, on ``tile`` at texel coordinates ``(a, b)``."""
    if leaf_tri >= 0:
        return vertex_normal(faces, vnormals, leaf_tri, a, b)
    return tile_normal(atlas_normal, tiles_i[tile, TILE_OFFSET], tiles_i[tile, TILE_RES], a, b)


@njit(cache=True)
def closest_hit(nb, nchild, ncount, tris, tri_face, faces, vnormals,
                tiles, tiles_i, atlas_depth, atlas_normal, discs, disc_point,
                ox, oy, oz, dx, dy, dz, t_min, t_max, stack, fp0, spread, n_levels):
    """Nearest hit along the ray in ``[t_min, t_max]``.

    With ``n_levels`` mip levels, a tile is searched at the level whose texels
    match the ray's footprint ``fp0 + spread * t`` where the ray enters the leaf.

    Returns ``(t, nx, ny, nz, face, tile, a, b)``: ``t = inf`` on a miss; the unit
    shading normal; the mesh face (triangle hits) or the cloud's point (disc hits),
    else -1, or tile (tile hits, else -1); barycentrics ``(a, b)`` of a triangle hit
    or texel coordinates of a tile hit (0 for a disc).
    """
    ix, iy, iz = _inv(dx), _inv(dy), _inv(dz)
    # With d = 0 the huge inverse is positive: min planes are near, max planes far.
    lx, hx = slab_origins(ox, dx)
    ly, hy = slab_origins(oy, dy)
    lz, hz = slab_origins(oz, dz)
    ob = (lx, ly, lz, hx, hy, hz)
    best = t_max
    face = -1
    best_k = -1
    best_disc = -1
    tile = -1
    ha = hb = 0.0
    if ray_box(nb, 0, ob, ix, iy, iz, t_min, best) == math.inf:
        return math.inf, 0.0, 0.0, 0.0, -1, -1, 0.0, 0.0
    sp = 0
    node = 0
    while True:
        c = ncount[node]
        if c == 0:
            left = nchild[node]
            tl = ray_box(nb, left, ob, ix, iy, iz, t_min, best)
            tr = ray_box(nb, left + 1, ob, ix, iy, iz, t_min, best)
            if tl != math.inf or tr != math.inf:
                if tl <= tr:
                    node = left
                    if tr != math.inf:
                        stack[sp] = left + 1
                        sp += 1
                else:
                    node = left + 1
                    if tl != math.inf:
                        stack[sp] = left
                        sp += 1
                continue
        elif c > 0:
            first = nchild[node]
            for k in range(first, first + c):
                t, u, v = intersect_triangle(tris, k, ox, oy, oz, dx, dy, dz, t_min, best)
                if t < best:
                    best, face, best_k, best_disc, tile, ha, hb = t, tri_face[k], k, -1, -1, u, v
        elif c < TILE_LEAF:
            first = nchild[node]
            for k in range(first, first - 1 - c):
                t = intersect_disc(discs, k, ox, oy, oz, dx, dy, dz, t_min, best)
                if t < best:
                    best, face, best_k, best_disc, tile, ha, hb = t, disc_point[k], -1, k, -1, 0.0, 0.0
        else:
            k = nchild[node]
            if n_levels > 1:
                k = mip_tile(k, ray_box(nb, node, ob, ix, iy, iz, t_min, best), fp0, spread,
                              n_levels, tiles, tiles.shape[0] // n_levels)
            t, s, u = tile_hit(k, ox, oy, oz, dx, dy, dz, t_min, best, tiles, tiles_i, atlas_depth)
            if t < best:
                best, face, best_k, best_disc, tile, ha, hb = t, -1, -1, -1, k, s, u
        # Pop the next node that the ray still reaches before the best hit.
        found = False
        while sp > 0:
            sp -= 1
            node = stack[sp]
            if ray_box(nb, node, ob, ix, iy, iz, t_min, best) != math.inf:
                found = True
                break
        if not found:
            break
    if face < 0 and tile < 0:
        return math.inf, 0.0, 0.0, 0.0, -1, -1, 0.0, 0.0
    if best_disc >= 0:
        nx, ny, nz = discs[best_disc, 3], discs[best_disc, 4], discs[best_disc, 5]
    else:
        nx, ny, nz = hit_normal(faces, vnormals, tiles_i, atlas_normal, best_k, tile, ha, hb)
    return best, nx, ny, nz, face, tile, ha, hb


@njit(cache=True, parallel=True)
def cast_rays(nb, nchild, ncount, tris, tri_face, faces, vnormals,
              tiles, tiles_i, atlas_depth, atlas_normal, discs, disc_point,
              origins, dirs, t_min, t_max, stack_size, fp0, spread, n_levels,
              out_t, out_n, out_face, out_tile, out_uv):
    """Closest hits of a batch of rays (unit directions), in parallel chunks.

    ``fp0 + spread * t`` is the rays' footprint for mip selection (0, 0: finest).
    """
    n = origins.shape[0]
    n_chunks = (n + RAY_CHUNK - 1) // RAY_CHUNK
    for c in prange(n_chunks):
        stack = np.empty(stack_size, np.int32)
        for r in range(c * RAY_CHUNK, min(n, (c + 1) * RAY_CHUNK)):
            t, nx, ny, nz, f, tl, a, b = closest_hit(
                nb, nchild, ncount, tris, tri_face, faces, vnormals,
                tiles, tiles_i, atlas_depth, atlas_normal, discs, disc_point,
                origins[r, 0], origins[r, 1], origins[r, 2], dirs[r, 0], dirs[r, 1], dirs[r, 2],
                t_min, t_max, stack, fp0, spread, n_levels)
            out_t[r] = t
            out_n[r, 0], out_n[r, 1], out_n[r, 2] = nx, ny, nz
            out_face[r], out_tile[r] = f, tl
            out_uv[r, 0], out_uv[r, 1] = a, b


@njit(cache=True, parallel=True)
def cast_primary(nb, nchild, ncount, tris, tri_face, faces, vnormals,
                 tiles, tiles_i, atlas_depth, atlas_normal, discs, disc_point,
                 params, width, height, stack_size, n_levels,
                 out_t, out_n, out_face, out_tile, out_uv):
    """Closest hits of the camera's primary rays, parallel over pixel tiles.

    Outputs are per pixel: ``out_t`` (H, W), ``out_n`` (H, W, 3), ``out_face`` and
    ``out_tile`` (H, W), ``out_uv`` (H, W, 2).
    """
    # A pixel's footprint: its angle times the distance (perspective) or its
    # fixed width (orthographic); U and V of the camera span half the view.
    pixel = 2.0 * math.sqrt(params[9] * params[9] + params[10] * params[10] + params[11] * params[11]) / height
    fp0 = 0.0 if params[12] != 0.0 else pixel
    spread = pixel if params[12] != 0.0 else 0.0
    for tile in prange(tile_count(width, height)):
        stack = np.empty(stack_size, np.int32)
        x0, x1, y0, y1 = tile_bounds(tile, width, height)
        for py in range(y0, y1):
            for px in range(x0, x1):
                ox, oy, oz, dx, dy, dz = primary_ray(params, px, py, width, height)
                t, nx, ny, nz, f, tl, a, b = closest_hit(
                    nb, nchild, ncount, tris, tri_face, faces, vnormals,
                    tiles, tiles_i, atlas_depth, atlas_normal, discs, disc_point,
                    ox, oy, oz, dx, dy, dz, 0.0, np.inf, stack, fp0, spread, n_levels)
                out_t[py, px] = t
                out_n[py, px, 0], out_n[py, px, 1], out_n[py, px, 2] = nx, ny, nz
                out_face[py, px], out_tile[py, px] = f, tl
                out_uv[py, px, 0], out_uv[py, px, 1] = a, b
