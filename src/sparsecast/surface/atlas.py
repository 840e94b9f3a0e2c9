"""The tile atlas: per-leaf orthographic projections, a texel pool, rasterization.

Each RBVH leaf becomes a square ``R x R`` height-field tile: its primitives are
projected orthographically along the leaf's mean normal ``W`` onto a rectangle
spanned by ``U`` and ``V`` (12 floats: ``O, U, V, W``; see :mod:`._rbvh_kernels`),
rasterized as the height nearest to a viewer on the ``+W`` side plus a normal
layer, and given a :data:`BORDER` of dilated texels.

**Layout for the CPU's caches.** A GPU samples tiles from a 2-D texture atlas; a
CPU ray reads a tile's texels row by row, and in a 2-D atlas each of a tile's rows
is a cache line of its own, a whole atlas row away from the next (a tile of
``R = 8`` in a 1 500-texel-wide atlas: eight lines 6 kB apart). Here every tile's
``R x R`` texels are one contiguous run of a 1-D pool (row-major, tiles in leaf
order, so neighbouring leaves are neighbours in memory), and the tile's record
(projection, height range, pool offset and ``R``) is one 64-byte line
(:data:`._rbvh_kernels.TILE_WORDS`): a tile test touches its record's line and
the few consecutive lines of its texels. On dragons-7m (51 k tiles of mostly
``R = 6-8``) that made the RBVH's primary frames 15 % faster than the 2-D atlas
with separate projection / height / rectangle arrays, with the same hits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._atlas_kernels import dilate, rasterize_triangles, splat_points, tile_height_range, triangle_tile_extents
from ..errors import ParameterError
from ._rbvh_kernels import EMPTY, EMPTY_TEST, NORMAL_SCALE, TILE_H, TILE_OFFSET, TILE_RES, TILE_WORDS

__all__ = ["Atlas", "BORDER", "pool_offsets", "tile_records", "tile_frames", "build_atlas", "atlas_texels",
           "read_layer"]

#: dilated texels around the covered interior of every tile
BORDER = 1
#: smallest interior resolution: coarser tiles would make the dilated border as
#: wide as the tile itself
MIN_RES = 4
#: steepest height gradient the dilation extrapolates (tan 65 deg, the widest cone)
MAX_SLOPE = 2.2


@dataclass(frozen=True)
class Atlas:
    """Tiles and their texels.

    Attributes
    ----------
    tiles : (T, 16) float32
        One 64-byte record per tile (:func:`tile_records`): ``O, U, V, W`` in
        ``[:12]``, the height range of the valid texels (plus a margin) in
        ``[12:14]``, and as int32 bits the tile's offset in the pool and its ``R``
        in ``[14]``, ``[15]``.
    depth : (N,) float32
        The texel pool: tile ``k``'s texel ``(i, j)`` is ``depth[offset_k + j R_k + i]``;
        ``EMPTY`` where no primitive covers a texel.
    normal : (N, 3) int8
        Unit normals times 127, aligned with ``depth``.
    boxes : (T, 2, 3) float32
        World bounding box of each leaf's surface, all levels (for the BVH over leaves).
    levels : int
        Mip levels; the tile arrays hold ``levels * T`` rows, level by level.
    """

    tiles: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    boxes: np.ndarray
    levels: int = 1

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in (self.tiles, self.depth, self.normal)))


def pool_offsets(res: np.ndarray) -> tuple[np.ndarray, int]:
    """Pool offsets of tiles of edge ``res`` laid out one after another: ``(offsets (T,) int64, texels)``.

    Raises :class:`ParameterError` past 2**31 texels (the records hold offsets as int32;
    8 GiB of depths alone, far beyond any quality preset of a mesh that fits in memory).
    """
    res = np.asarray(res, dtype=np.int64)
    size = res * res
    total = int(size.sum())
    if total >= 2**31:
        raise ParameterError(f"atlas: {total} texels, over the 2**31 a tile record's int32 offset "
                             f"addresses; choose a coarser quality")
    return np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64), total


def tile_records(proj: np.ndarray, height: np.ndarray, offset: np.ndarray, res: np.ndarray) -> np.ndarray:
    """The (T, 16) float32 tile records the traversal reads, each on a 64-byte boundary.

    Parameters
    ----------
    proj : (T, 12)
        ``O, U, V, W`` per tile.
    height : (T, 2)
        Height range of its valid texels.
    offset, res : (T,) int
        Pool offset and edge ``R`` (stored as int32 bits in the record's last two words).
    """
    n = len(proj)
    buf = np.empty(n * TILE_WORDS + 16, np.float32)
    skip = (-buf.ctypes.data % 64) // 4
    rec = buf[skip:skip + n * TILE_WORDS].reshape(n, TILE_WORDS)
    rec[:, :12] = proj
    rec[:, TILE_H:TILE_H + 2] = height
    bits = rec.view(np.int32)
    bits[:, TILE_OFFSET] = offset
    bits[:, TILE_RES] = res
    return rec


def tile_frames(normals: np.ndarray) -> np.ndarray:
    """Orthonormal ``(u, v, w)`` rows per tile, ``w`` the given (mean) normal."""
    w = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    # The world axis least aligned with w gives a well-conditioned cross product.
    a = np.zeros_like(w)
    a[np.arange(len(w)), np.argmin(np.abs(w), axis=1)] = 1.0
    u = np.cross(w, a)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(w, u)
    return np.stack([u, v, w], axis=1)


def _segment_reduce(values: np.ndarray, starts: np.ndarray, op) -> np.ndarray:
    """``op`` over each contiguous segment of rows (every segment non-empty)."""
    return op.reduceat(values, starts, axis=0)


def build_atlas(normals: np.ndarray, res: np.ndarray, tile_start: np.ndarray, tile_count: np.ndarray,
                refs: np.ndarray, *, tris: np.ndarray | None = None, faces=None, vnormals=None,
                points: np.ndarray | None = None, pnormals=None, radii=None, levels: int = 1) -> Atlas:
    """Project, pack and rasterize one tile per leaf and mip level.

    Parameters
    ----------
    normals : (T, 3)
        Leaf mean normals (projection directions).
    res : (T,) int
        Interior resolution per tile (texels along an edge, without the border).
    tile_start, tile_count, refs
        Primitive references of each leaf, contiguous and in tile order (every
        tile holds at least one).
    tris, faces, vnormals
        Triangle corners (m, 3, 3), faces and vertex normals (triangle meshes), or
    points, pnormals, radii
        Disc centres, normals and radii (point clouds).
    levels : int
        Mip levels: level ``L`` of leaf ``k`` is tile ``k + L T`` with half the
        resolution of level ``L - 1`` (at least :data:`MIN_RES`), rasterized from
        the primitives again (not filtered), so every level is crack-free.
    """
    n_tiles = len(res)
    frames = tile_frames(np.asarray(normals, np.float64))
    starts = np.asarray(tile_start, np.int64)
    if tris is not None:
        lo, hi, prim_lo, prim_hi = triangle_tile_extents(frames, starts, np.asarray(tile_count, np.int64),
                                                         refs, tris)
    else:
        seg = np.repeat(np.arange(n_tiles), tile_count)
        c = np.einsum("rak,rk->ra", frames[seg], points[refs])
        rr = radii[refs][:, None]
        lo = _segment_reduce(c - rr, starts, np.minimum)
        hi = _segment_reduce(c + rr, starts, np.maximum)
        prim_lo = _segment_reduce(points[refs] - rr, starts, np.minimum)
        prim_hi = _segment_reduce(points[refs] + rr, starts, np.maximum)
    res0 = np.maximum(np.asarray(res, np.int64), MIN_RES)
    ext = hi[:, :2] - lo[:, :2]
    # Every level as a set of tiles of its own: same frames and primitives, coarser texels.
    res_l = [np.maximum(np.ceil((res0 - 1) / 2**lv).astype(np.int64) + 1, MIN_RES) for lv in range(levels)]
    res_all = np.concatenate(res_l)
    frames_all = np.tile(frames, (levels, 1, 1))
    lo_all, ext_all = np.tile(lo, (levels, 1)), np.tile(ext, (levels, 1))
    # A degenerate (line-like) extent still needs a finite texel size.
    steps = np.maximum(ext_all / (res_all[:, None] - 1), 1e-6 * ext_all.max(axis=1, keepdims=True) + 1e-30)
    r_tot = res_all + 2 * BORDER
    origin_uvw = np.stack([lo_all[:, 0] - BORDER * steps[:, 0], lo_all[:, 1] - BORDER * steps[:, 1],
                           lo_all[:, 2]], 1)
    o = np.einsum("ta,tak->tk", origin_uvw, frames_all)
    proj = np.concatenate([o, frames_all[:, 0] / steps[:, :1], frames_all[:, 1] / steps[:, 1:],
                           frames_all[:, 2]], axis=1)
    offset, n_texels = pool_offsets(r_tot)
    texels = np.stack([offset, r_tot], axis=1).astype(np.int64)
    depth = np.full(n_texels, EMPTY, np.float32)
    normal = np.zeros((n_texels, 3), np.float32)
    start = np.tile(starts, levels)
    count = np.tile(np.asarray(tile_count, np.int64), levels)
    if tris is not None:
        # Conservative: the extrapolated rim is the border (see rasterize_triangles).
        rasterize_triangles(proj, texels, start, count, refs, tris, faces, vnormals, depth, normal)
    else:
        splat_points(proj, texels, steps, start, count, refs, points, pnormals, radii, depth, normal)
        dilate(texels, steps, depth, normal, BORDER, MAX_SLOPE)
    pad = 0.01 * steps.max(axis=1)  # keep grazing hits at the extreme heights
    tile_h = tile_height_range(texels, depth, pad)
    # World box of a leaf: its oriented boxes (all levels), cut down to the
    # primitives' box grown by the border (the conservative rim reaches under one
    # texel of the coarsest level out).
    u, v, wv = frames_all[:, 0], frames_all[:, 1], frames_all[:, 2]
    ext_s = ((r_tot - 1) * steps[:, 0])[:, None]
    ext_t = ((r_tot - 1) * steps[:, 1])[:, None]
    corners = np.stack([o + a * ext_s * u + b * ext_t * v + tile_h[:, c:c + 1] * wv
                        for a in (0, 1) for b in (0, 1) for c in (0, 1)])
    obb_lo = corners.min(axis=0).reshape(levels, n_tiles, 3).min(axis=0)
    obb_hi = corners.max(axis=0).reshape(levels, n_tiles, 3).max(axis=0)
    grow = BORDER * steps.max(axis=1).reshape(levels, n_tiles).max(axis=0)
    box_lo = np.maximum(obb_lo, prim_lo - grow[:, None])
    box_hi = np.minimum(obb_hi, prim_hi + grow[:, None])
    boxes = np.stack([box_lo, box_hi], axis=1).astype(np.float32)
    nrm = np.clip(np.rint(normal * NORMAL_SCALE), -127, 127).astype(np.int8)
    return Atlas(tile_records(proj, tile_h, offset, r_tot), depth, nrm, boxes, levels)


# -- the atlas as surface storage -------------------------------------------------
def atlas_texels(index) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World position, unit normal and pool index of every valid texel.

    The positions lie on the rasterized surface, so attributes computed there
    (ambient occlusion, paint, irradiance) can be written into an extra layer of
    the pool's shape (``index.atlas_depth.shape``: ``layer[texel] = value``) and
    read back at ray hits with :func:`read_layer`.
    """
    idx, pos, nrm = [], [], []
    proj = index.tile_proj.astype(np.float64)
    for k, (o, r) in enumerate(zip(index.tile_offset.tolist(), index.tile_res.tolist())):
        d = index.atlas_depth[o:o + r * r].reshape(r, r)
        j, i = np.nonzero(d > EMPTY_TEST)
        p = proj[k]
        u, v, w = p[3:6], p[6:9], p[9:12]
        # U and V carry the inverse texel spacing: the world step along U is U / |U|^2.
        world = p[:3] + i[:, None] * (u / (u @ u)) + j[:, None] * (v / (v @ v)) + d[j, i][:, None] * w
        idx.append(o + j * r + i)
        pos.append(world)
    if not idx:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int64)
    texel = np.concatenate(idx).astype(np.int64)
    n = index.atlas_normal[texel].astype(np.float64)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return np.concatenate(pos), n, texel


def read_layer(index, layer: np.ndarray, tile: np.ndarray, uv: np.ndarray, default: float = np.nan) -> np.ndarray:
    """Bilinear lookup of a pool-shaped ``layer`` (N,) at tile hits (``Hits.tile``, ``Hits.uv``).

    Hits that are not on a tile (misses, exact triangle leaves) get ``default``.
    """
    tile = np.asarray(tile)
    layer = np.asarray(layer)
    if layer.shape[:1] != index.atlas_depth.shape:
        raise ParameterError(f"layer: expected one value per pool texel, shape {index.atlas_depth.shape}, "
                             f"got {layer.shape}")
    out = np.full(tile.shape, default, dtype=np.float64)
    on = tile >= 0
    if not on.any():
        return out
    base = index.tile_offset[tile[on]].astype(np.int64)
    r = index.tile_res[tile[on]].astype(np.int64)
    s, t = uv[on][:, 0].astype(np.float64), uv[on][:, 1].astype(np.float64)
    i = np.clip(np.floor(s).astype(np.int64), 0, r - 2)
    j = np.clip(np.floor(t).astype(np.int64), 0, r - 2)
    fs, ft = s - i, t - j
    a = base + j * r + i
    out[on] = ((1 - ft) * ((1 - fs) * layer[a] + fs * layer[a + 1])
               + ft * ((1 - fs) * layer[a + r] + fs * layer[a + r + 1]))
    return out
