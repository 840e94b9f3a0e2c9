"""The tile atlas: per-leaf orthographic projections, row-wise packing, rasterization.

Each RBVH leaf becomes a square ``R x R`` height-field tile: its primitives are
projected orthographically along the leaf's mean normal ``W`` onto a rectangle
spanned by ``U`` and ``V`` (12 floats: ``O, U, V, W``; see :mod:`._rbvh_kernels`),
rasterized as the height nearest to a viewer on the ``+W`` side plus a normal
layer, and given a :data:`BORDER` of dilated texels. Tiles are sorted by
resolution and packed into shelves (rows) of one atlas.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._atlas_kernels import dilate, rasterize_triangles, splat_points, tile_height_range, triangle_tile_extents
from ._rbvh_kernels import EMPTY, EMPTY_TEST, NORMAL_SCALE

__all__ = ["Atlas", "BORDER", "pack_tiles", "tile_frames", "build_atlas", "atlas_texels", "read_layer"]

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
    tile_proj : (T, 12) float32
        ``O, U, V, W`` per tile.
    tile_h : (T, 2) float32
        Height range of the valid texels (plus a margin).
    tile_rect : (T, 3) int32
        ``x0, y0, R`` of the tile in the atlas.
    depth : (H, W) float32
        Heights; ``EMPTY`` where no primitive covers a texel.
    normal : (H, W, 3) int8
        Unit normals times 127.
    boxes : (T, 2, 3) float32
        World bounding box of each leaf's surface, all levels (for the BVH over leaves).
    levels : int
        Mip levels; the tile arrays hold ``levels * T`` rows, level by level.
    """

    tile_proj: np.ndarray
    tile_h: np.ndarray
    tile_rect: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    boxes: np.ndarray
    levels: int = 1

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in (self.tile_proj, self.tile_h, self.tile_rect, self.depth, self.normal)))


def pack_tiles(res: np.ndarray) -> tuple[np.ndarray, tuple[int, int]]:
    """Shelf packing of square tiles of edge ``res``: largest first, left to right, row by row.

    Returns ``(rect (T, 3) int32 with x0, y0, R; (height, width))``. Tiles never
    overlap: within a row x-ranges are disjoint, and a row is as tall as its
    first (largest) tile.
    """
    res = np.asarray(res, dtype=np.int64)
    rect = np.zeros((len(res), 3), np.int32)
    if len(res) == 0:
        return rect, (1, 1)
    width = int(max(res.max(), np.ceil(np.sqrt(np.sum(res * res) * 1.05))))
    order = np.argsort(-res, kind="stable")
    x = y = row_h = 0
    for k in order:
        r = int(res[k])
        if x + r > width:
            y += row_h
            x = row_h = 0
        if row_h == 0:
            row_h = r
        rect[k] = (x, y, r)
        x += r
    return rect, (y + row_h, width)


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
    rect, (h, w) = pack_tiles(r_tot)
    depth = np.full((h, w), EMPTY, np.float32)
    normal = np.zeros((h, w, 3), np.float32)
    start = np.tile(starts, levels)
    count = np.tile(np.asarray(tile_count, np.int64), levels)
    if tris is not None:
        # Conservative: the extrapolated rim is the border (see rasterize_triangles).
        rasterize_triangles(proj, rect, start, count, refs, tris, faces, vnormals, depth, normal)
    else:
        splat_points(proj, rect, steps, start, count, refs, points, pnormals, radii, depth, normal)
        dilate(rect, steps, depth, normal, BORDER, MAX_SLOPE)
    pad = 0.01 * steps.max(axis=1)  # keep grazing hits at the extreme heights
    tile_h = tile_height_range(rect, depth, pad)
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
    return Atlas(proj.astype(np.float32), tile_h, rect, depth, nrm, boxes, levels)


# -- the atlas as surface storage -------------------------------------------------
def atlas_texels(index) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World position, unit normal and atlas ``(row, col)`` of every valid texel.

    The positions lie on the rasterized surface, so attributes computed there
    (ambient occlusion, paint, irradiance) can be written into an extra layer of
    the atlas's shape and read back at ray hits with :func:`read_layer`.
    """
    rows, cols, pos, nrm = [], [], [], []
    for k, (x0, y0, r) in enumerate(index.tile_rect):
        d = index.atlas_depth[y0:y0 + r, x0:x0 + r]
        j, i = np.nonzero(d > EMPTY_TEST)
        p = index.tile_proj[k].astype(np.float64)
        u, v, w = p[3:6], p[6:9], p[9:12]
        # U and V carry the inverse texel spacing: the world step along U is U / |U|^2.
        world = p[:3] + i[:, None] * (u / (u @ u)) + j[:, None] * (v / (v @ v)) + d[j, i][:, None] * w
        rows.append(y0 + j)
        cols.append(x0 + i)
        pos.append(world)
        nrm.append(index.atlas_normal[y0 + j, x0 + i].astype(np.float64))
    if not rows:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2), np.int64)
    n = np.concatenate(nrm)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return np.concatenate(pos), n, np.stack([np.concatenate(rows), np.concatenate(cols)], 1)


def read_layer(index, layer: np.ndarray, tile: np.ndarray, uv: np.ndarray, default: float = np.nan) -> np.ndarray:
    """Bilinear lookup of an atlas-shaped ``layer`` at tile hits (``Hits.tile``, ``Hits.uv``).

    Hits that are not on a tile (misses, exact triangle leaves) get ``default``.
    """
    tile = np.asarray(tile)
    out = np.full(tile.shape, default, dtype=np.float64)
    on = tile >= 0
    if not on.any():
        return out
    rect = index.tile_rect[tile[on]]
    s, t = uv[on][:, 0].astype(np.float64), uv[on][:, 1].astype(np.float64)
    i = np.clip(np.floor(s).astype(np.int64), 0, rect[:, 2] - 2)
    j = np.clip(np.floor(t).astype(np.int64), 0, rect[:, 2] - 2)
    fs, ft = s - i, t - j
    x, y = rect[:, 0] + i, rect[:, 1] + j
    out[on] = ((1 - ft) * ((1 - fs) * layer[y, x] + fs * layer[y, x + 1])
               + ft * ((1 - fs) * layer[y + 1, x] + fs * layer[y + 1, x + 1]))
    return out
