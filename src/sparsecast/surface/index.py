"""The flattened surface index both builders produce, and :func:`raycast` (:class:`RayCast`) over it.

A :class:`SurfaceIndex` is a BVH whose leaves are triangles or discs (exact) or
height-field tiles in an atlas (approximate); the exact BVH has no tiles, the
hybrid RBVH has both. In the binary layout one traversal kernel serves every
kind (:func:`._bvh_kernels.closest_hit`); by default the exact BVH of a mesh is
in the 4-wide layout instead (:mod:`.wide`, traversed by :mod:`._wide_kernels`),
and so is the RBVH (:mod:`.rbvh_wide`, traversed by :mod:`._rbvh_wide_kernels`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError
from ._bvh_kernels import TILE_LEAF, cast_primary, cast_rays
from ._rbvh_kernels import TILE_H, TILE_OFFSET, TILE_RES, TILE_WORDS
from ._rbvh_wide_kernels import cast_primary_rbvh_wide, cast_rays_rbvh_wide
from ._wide_kernels import cast_primary_wide, cast_rays_wide, root_slab
from .rbvh_wide import WideRBVH
from .wide import WideBVH

__all__ = ["SurfaceIndex", "Hits", "RayCast", "raycast", "empty_atlas_arrays"]


def empty_atlas_arrays() -> dict[str, np.ndarray]:
    """Tile arrays of an index without tiles (dtypes as the kernels expect)."""
    return dict(
        tiles=np.zeros((0, TILE_WORDS), np.float32),
        atlas_depth=np.zeros(1, np.float32),
        atlas_normal=np.zeros((1, 3), np.int8),
    )


@dataclass(frozen=True, eq=False)
class SurfaceIndex:
    """Flattened BVH over triangles and/or height-field tiles.

    Attributes
    ----------
    kind : str
        ``"bvh"`` (exact) or ``"rbvh"`` (rasterized, possibly hybrid).
    node_bounds : (n, 2, 3) float32
    node_child, node_count : (n,) int32
        The binary layout; see :mod:`._bvh_kernels` for the encoding. Empty
        (``n = 0``) when the index is in a wide layout (``wide`` or ``wide_rbvh``).
    tris : (k, 3, 3) float32
        Triangles of the triangle leaves in leaf order; ``tri_face`` maps them to
        mesh faces (for normals). Empty in the wide layout.
    faces, vnormals : (k, 3) int32 and float32 normals
        Shading: leaf triangle ``k`` has corner normals ``vnormals[faces[k]]``; in
        the wide layout ``k`` is the mesh face.
    tiles : (T, 16) float32
        One 64-byte record per tile (projection, height range, pool offset and
        edge; see :mod:`._rbvh_kernels`); :attr:`tile_proj`, :attr:`tile_h`,
        :attr:`tile_offset` and :attr:`tile_res` are views of its fields.
    atlas_depth : (N,) float32
        The texel pool: every tile's ``R x R`` depths, row by row (:mod:`.atlas`).
    atlas_normal : (N, 3) int8
        The int8 normal layer, aligned with ``atlas_depth``.
    discs : (d, 7) float32
        Discs of the disc leaves in leaf order (an exact BVH over a point cloud):
        centre, unit normal, radius; ``disc_point`` (d,) int32 maps them to the
        cloud's points.
    depth : int
        Depth of the binary tree (the binary traversal's stack size).
    mip_levels : int
        Tile rows ``k + L n_leaf_tiles`` hold mip level ``L`` of leaf tile ``k``.
    build : dict
        ``ms`` and per-phase milliseconds, plus builder parameters.
    wide : WideBVH, optional
        The exact BVH's 4-wide layout (triangles in packets).
    wide_rbvh : WideRBVH, optional
        The RBVH's 4-wide layout (its leaves index ``tris`` and the tile arrays).
    """

    kind: str
    source: Any
    node_bounds: np.ndarray
    node_child: np.ndarray
    node_count: np.ndarray
    tris: np.ndarray
    tri_face: np.ndarray
    faces: np.ndarray
    vnormals: np.ndarray
    tiles: np.ndarray
    atlas_depth: np.ndarray
    atlas_normal: np.ndarray
    depth: int
    build: dict = field(default_factory=dict)
    mip_levels: int = 1
    layers: dict = field(default_factory=dict)  # extra atlas layers (surface storage)
    discs: np.ndarray = field(default_factory=lambda: np.zeros((0, 7), np.float32))
    disc_point: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    wide: WideBVH | None = None
    wide_rbvh: WideRBVH | None = None

    @property
    def layout(self) -> str:
        """``"wide"`` (4-wide nodes) or ``"binary"``."""
        return "binary" if self.wide is None and self.wide_rbvh is None else "wide"

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float32: the box of everything the index holds."""
        if self.wide is not None:
            return self.wide.root
        if self.wide_rbvh is not None:
            return self.wide_rbvh.root
        return self.node_bounds[0]

    @property
    def center(self) -> np.ndarray:
        return self.bounds.mean(axis=0).astype(np.float64)

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(np.ptp(self.bounds.astype(np.float64), axis=0)))

    @property
    def n_tiles(self) -> int:
        """Tiles of the finest level (one per tile leaf)."""
        return int(self.tiles.shape[0]) // self.mip_levels

    @property
    def tile_proj(self) -> np.ndarray:
        """(T, 12) float32 view: ``O, U, V, W`` of every tile (all mip levels)."""
        return self.tiles[:, :12]

    @property
    def tile_h(self) -> np.ndarray:
        """(T, 2) float32 view: height range of every tile's valid texels."""
        return self.tiles[:, TILE_H:TILE_H + 2]

    @property
    def tile_offset(self) -> np.ndarray:
        """(T,) int32 view: where every tile's texels start in the pool (``atlas_depth``)."""
        return self.tiles.view(np.int32)[:, TILE_OFFSET]

    @property
    def tile_res(self) -> np.ndarray:
        """(T,) int32 view: every tile's edge ``R`` in texels (``R x R`` texels)."""
        return self.tiles.view(np.int32)[:, TILE_RES]

    def kernel_args(self) -> tuple:
        """The arrays every binary-layout traversal kernel takes, in order."""
        return (self.node_bounds, self.node_child, self.node_count, self.tris, self.tri_face,
                self.faces, self.vnormals, self.tiles, self.tiles.view(np.int32),
                self.atlas_depth, self.atlas_normal, self.discs, self.disc_point)

    def _rbvh_wide_args(self) -> tuple:
        w = self.wide_rbvh
        return (w.nodes, w.nodes.view(np.int32), self.tris, self.tri_face, self.faces, self.vnormals,
                self.tiles, self.tiles.view(np.int32), self.atlas_depth, self.atlas_normal, root_slab(w.root))

    def ray_call(self, origins: np.ndarray, dirs: np.ndarray, t_min: float, t_max: float,
                 footprint: tuple[float, float], out: tuple) -> tuple[Any, tuple]:
        """``(kernel, args)``: ``kernel(*args)`` casts rays ``origins``, ``dirs`` (n, 3) float64
        (unit directions) into ``out = (t (n,), normals (n, 3), face (n,), tile (n,), uv (n, 2))``."""
        if self.wide is not None:
            w = self.wide
            return cast_rays_wide, (*w.kernel_args(), self.faces, self.vnormals, root_slab(w.root),
                                    origins, dirs, t_min, t_max, w.stack_size, *out)
        if self.wide_rbvh is not None:
            return cast_rays_rbvh_wide, (*self._rbvh_wide_args(), origins, dirs, t_min, t_max,
                                         self.wide_rbvh.stack_size, footprint[0], footprint[1],
                                         self.mip_levels, *out)
        return cast_rays, (*self.kernel_args(), origins, dirs, t_min, t_max, self.depth + 2,
                           footprint[0], footprint[1], self.mip_levels, *out)

    def primary_call(self, params: np.ndarray, width: int, height: int, out: tuple) -> tuple[Any, tuple]:
        """``(kernel, args)``: ``kernel(*args)`` casts the primary rays of camera ``params``
        (:meth:`sparsecast.Camera.ray_params`) into per-pixel ``out`` (as :meth:`ray_call`'s, (H, W, ...))."""
        if self.wide is not None:
            w = self.wide
            return cast_primary_wide, (*w.kernel_args(), self.faces, self.vnormals, root_slab(w.root),
                                       params, width, height, w.stack_size, *out)
        if self.wide_rbvh is not None:
            return cast_primary_rbvh_wide, (*self._rbvh_wide_args(), params, width, height,
                                            self.wide_rbvh.stack_size, self.mip_levels, *out)
        return cast_primary, (*self.kernel_args(), params, width, height, self.depth + 2, self.mip_levels, *out)

    def nbytes(self) -> dict[str, int]:
        """Bytes of the tree, the triangles it stores, the atlas and the shading data."""
        tiles = self.n_tiles > 0
        wide = self.wide.nbytes() if self.wide is not None else {"nodes": 0, "triangles": 0}
        if self.wide_rbvh is not None:
            wide["nodes"] += self.wide_rbvh.nbytes()
        return {
            "nodes": int(self.node_bounds.nbytes + self.node_child.nbytes + self.node_count.nbytes) + wide["nodes"],
            "triangles": int(self.tris.nbytes + self.tri_face.nbytes) + wide["triangles"],
            "discs": int(self.discs.nbytes + self.disc_point.nbytes),
            "atlas": int(self.atlas_depth.nbytes + self.atlas_normal.nbytes + self.tiles.nbytes) if tiles else 0,
            # Smooth shading of triangle hits: corner indices and vertex normals.
            "shading": int(self.faces.nbytes + self.vnormals.nbytes),
        }

    def stats(self) -> dict[str, Any]:
        """Node / leaf counts, depth, bytes, build time per phase."""
        c = self.node_count
        b = self.nbytes()
        w = self.wide
        n_nodes = len(c) if w is None else len(w.nodes)
        if self.wide_rbvh is not None:
            c = self.wide_rbvh.leaf_counts()  # the leaves' binary codes: the counts below still hold
            n_nodes = len(self.wide_rbvh.nodes)
        out = {
            "kind": self.kind,
            "layout": self.layout,
            "nodes": int(n_nodes),
            "triangle_leaves": int((c > 0).sum()) if w is None else w.n_leaves,
            "tile_leaves": int((c == TILE_LEAF).sum()),
            "triangles": int(len(self.tris)) if w is None else int(np.count_nonzero(w.face4 >= 0)),
            "disc_leaves": int((c < TILE_LEAF).sum()),
            "discs": int(len(self.discs)),
            "tiles": self.n_tiles,
            "mip_levels": self.mip_levels,
            "texels": int(np.sum(self.tile_res.astype(np.int64) ** 2)) if self.n_tiles else 0,
            "depth": self.depth if w is None else w.depth,
            **({"wide_depth": self.wide_rbvh.depth} if self.wide_rbvh is not None else {}),
            "bytes": int(sum(b.values())),
            **{f"bytes_{k}": v for k, v in b.items()},
        }
        out.update(self.build)
        return out

    def __repr__(self) -> str:
        s = self.stats()
        return (f"<SurfaceIndex {self.kind}: {s['nodes']} nodes, {s['triangles']} triangles, "
                f"{s['discs']} discs, {s['tiles']} tiles, {s['bytes'] / 2**20:.1f} MiB>")


@dataclass(frozen=True)
class Hits:
    """Closest hits of a batch of rays (``t = inf`` where a ray misses).

    ``face`` is the mesh face of a triangle hit or the point of a disc hit (else -1), ``tile`` the atlas tile
    of a height-field hit (else -1); ``uv`` holds barycentrics for triangle hits
    and texel coordinates for tile hits.
    """

    t: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    face: np.ndarray
    tile: np.ndarray
    uv: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return np.isfinite(self.t)


def _rays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    o = np.asarray(origins, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    if o.ndim == 1:
        o = o[None]
    if o.ndim != 2 or o.shape[1] != 3:
        raise ParameterError(f"origins: expected shape (n, 3), got {np.shape(origins)}")
    if d.ndim == 1:
        d = d[None]
    if d.shape != o.shape and d.shape != (1, 3) and o.shape != (1, 3):
        raise ParameterError(f"directions: expected shape {o.shape} (or (3,)), got {np.shape(directions)}")
    o, d = np.broadcast_arrays(o, d)
    if not (np.isfinite(o).all() and np.isfinite(d).all()):
        raise ParameterError("origins/directions: expected finite numbers, found NaN or Inf")
    ln = np.linalg.norm(d, axis=1, keepdims=True)
    if (ln == 0).any():
        raise ParameterError(f"directions: {int((ln == 0).sum())} are zero vectors; expected non-zero directions")
    return np.ascontiguousarray(o), np.ascontiguousarray(d / ln)


class RayCast:
    """Rays against an index, checked and with their output arrays allocated once.

    :meth:`run` casts them (again; only the traversal kernel runs), :meth:`hits`
    reads the result. :func:`raycast` is ``RayCast(...).run().hits()``; a benchmark
    times :meth:`run` alone, so that checking and allocation stay out of the timing.

    Parameters are those of :func:`raycast`.
    """

    def __init__(self, index: SurfaceIndex, origins, directions, *, t_min: float = 0.0,
                 t_max: float = np.inf, footprint: tuple[float, float] = (0.0, 0.0)) -> None:
        if not isinstance(index, SurfaceIndex):
            raise ParameterError(f"index: expected a SurfaceIndex from build_bvh/build_rbvh, got {type(index).__name__}")
        if not (t_max >= t_min >= 0.0):
            raise ParameterError(f"t_min, t_max: expected 0 <= t_min <= t_max, got {t_min}, {t_max}")
        self.index = index
        self.origins, self.directions = _rays(origins, directions)
        n = len(self.origins)
        self.t = np.empty(n, np.float64)
        self.normals = np.empty((n, 3), np.float32)
        self.face = np.empty(n, np.int32)
        self.tile = np.empty(n, np.int32)
        self.uv = np.empty((n, 2), np.float32)
        fp0, spread = (float(x) for x in footprint)
        if not (fp0 >= 0 and spread >= 0):
            raise ParameterError(f"footprint: expected two non-negative numbers (w0, spread), got {footprint!r}")
        self._kernel, self._args = index.ray_call(self.origins, self.directions, float(t_min), float(t_max),
                                                  (fp0, spread), (self.t, self.normals, self.face, self.tile, self.uv))

    def run(self) -> "RayCast":
        """Cast every ray (the kernel fills the output arrays in place)."""
        self._kernel(*self._args)
        return self

    def hits(self) -> Hits:
        """The closest hits of the last :meth:`run`."""
        o, d, t = self.origins, self.directions, self.t
        pts = o + np.where(np.isfinite(t), t, np.nan)[:, None] * d
        return Hits(t, pts, self.normals, self.face, self.tile, self.uv)


def raycast(index: SurfaceIndex, origins, directions, *, t_min: float = 0.0,
            t_max: float = np.inf, footprint: tuple[float, float] = (0.0, 0.0)) -> Hits:
    """Closest hit of every ray ``origins[i] + t * directions[i]``, ``t`` in ``[t_min, t_max]``.

    Directions are normalised first, so ``t`` is a world-space distance.
    ``footprint = (w0, spread)``: the rays' width ``w0 + spread * t`` selects the
    mip level of an RBVH built with ``mip_levels > 1`` (default: the finest).
    """
    return RayCast(index, origins, directions, t_min=t_min, t_max=t_max, footprint=footprint).run().hits()
