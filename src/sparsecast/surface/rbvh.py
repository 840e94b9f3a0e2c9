"""Rasterized BVH construction (Novák & Dachsbacher, EG 2012), level by level on the CPU.

Every level of the tree is built at once (the paper's Fig. 7): per-node
reductions over the primitive references, a split-or-rasterize decision,
a split plane per node, and compaction of the references into the next level,
optionally copying primitives within +-5 % of a split plane into both children
(the paper's overlap; see ``overlap`` in :func:`build_rbvh`).

A node becomes a **tile leaf** when its surface is a height field worth
rasterizing: the cone of its normals opens less than ``phi``, its projected
area is a large enough share of its area (``A_perp / A > alpha``), and its tile
resolution ``R = sqrt(rho A^2 / A_perp)`` does not exceed the optimal-resolution
cap (the paper's fit ``5.76 ln(rho) - 42.99`` for coherent rays,
``1.23 ln(rho) - 0.17`` for incoherent ones). ``rho`` is a pixel-to-area ratio
on the mesh normalised to area 1.

**Hybrid RBVH**: where height fields do not fit (fewer than 8 triangles, or more
than 80 % of the corners at strongly curved vertices) the subtree becomes a plain
triangle BVH with exact triangle leaves, built by the same level loop without
duplication.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from . import _rbvh_build_kernels as K
from ._bvh_kernels import TILE_LEAF
from .atlas import MIN_RES, build_atlas
from .index import SurfaceIndex, empty_atlas_arrays
from .mesh import PointCloud, TriangleMesh
from .rbvh_wide import collapse_binary

__all__ = ["Quality", "QUALITY", "build_rbvh", "resolution_cap", "LAYOUTS"]

#: traversal layouts of :func:`build_rbvh` (the first is the default)
LAYOUTS = ("wide", "binary")


@dataclass(frozen=True)
class Quality:
    """A quality preset: pixel-to-area ratio ``rho`` (mesh area normalised to 1),
    projected-area ratio ``alpha``, and normal-cone opening ``phi_deg``."""

    rho: float
    alpha: float
    phi_deg: float


#: the paper's presets Q0 (finest) to Q4 (coarsest)
QUALITY = {
    "Q0": Quality(2 * 2**20, 0.85, 45.0),
    "Q1": Quality(2**20, 0.80, 50.0),
    "Q2": Quality(512 * 2**10, 0.75, 55.0),
    "Q3": Quality(128 * 2**10, 0.70, 60.0),
    "Q4": Quality(32 * 2**10, 0.65, 65.0),
}

#: hybrid rule: nodes with fewer triangles than this become triangle subtrees ...
HYBRID_MIN_TRIANGLES = 8
#: ... as do nodes with more than this share of corners at curved vertices
HYBRID_CURVY_SHARE = 0.8
#: triangles per leaf of the hybrid's triangle subtrees
TRI_LEAF = 4
#: the paper's overlap band: primitives within this share of the node's extent
#: of a split plane go to both children (``build_rbvh(..., overlap=OVERLAP)``)
OVERLAP = 0.05


def resolution_cap(rho: float, rays: str = "coherent") -> float:
    """The paper's optimal tile resolution for pixel-to-area ratio ``rho``."""
    if rays == "coherent":
        return 5.76 * math.log(rho) - 42.99
    if rays == "incoherent":
        return 1.23 * math.log(rho) - 0.17
    raise ParameterError(f"rays: expected 'coherent' or 'incoherent', got {rays!r}")


def _resolve_quality(quality) -> Quality:
    if isinstance(quality, Quality):
        return quality
    if isinstance(quality, str) and quality.upper() in QUALITY:
        return QUALITY[quality.upper()]
    raise ParameterError(f"quality: expected one of {', '.join(QUALITY)} or a Quality, got {quality!r}")


def _ranges(start: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Concatenated index ranges ``start[i] .. start[i] + count[i]``."""
    total = int(count.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    offs = np.repeat(start - np.concatenate([[0], np.cumsum(count)[:-1]]), count)
    return offs + np.arange(total)


@dataclass
class _Prims:
    """Per-primitive arrays the build kernels read."""

    pmin: np.ndarray
    pmax: np.ndarray
    pcent: np.ndarray
    pnorm: np.ndarray
    parea: np.ndarray
    pcurvy: np.ndarray
    pcomp: np.ndarray


def _mesh_prims(mesh: TriangleMesh, curvature_deg: float) -> _Prims:
    pmin, pmax, pcent, curvy = K.triangle_prims(mesh.triangles, mesh.faces, mesh.face_normals,
                                                mesh.vertex_normals, math.cos(math.radians(curvature_deg)))
    comp = K.face_components(mesh.faces, len(mesh.vertices))
    return _Prims(pmin, pmax, pcent, mesh.face_normals, mesh.face_areas, curvy, comp)


def _point_prims(pc: PointCloud) -> _Prims:
    r = np.asarray(pc.radii)[:, None]
    n = len(pc.points)
    return _Prims(pc.points - r, pc.points + r, pc.points, pc.normals, np.pi * r[:, 0] ** 2,
                  np.zeros(n), np.zeros(n, np.int32))


class _Nodes:
    """Growable flat node arrays (children are allocated in pairs)."""

    def __init__(self, cap: int) -> None:
        self.bounds = np.zeros((cap, 2, 3), np.float32)
        self.child = np.zeros(cap, np.int32)
        self.count = np.zeros(cap, np.int32)
        self.n = 1

    def alloc_pairs(self, k: int) -> np.ndarray:
        need = self.n + 2 * k
        if need > len(self.child):
            cap = max(need, 2 * len(self.child))
            self.bounds = np.resize(self.bounds, (cap, 2, 3))
            self.child = np.resize(self.child, cap)
            self.count = np.resize(self.count, cap)
        first = self.n + 2 * np.arange(k, dtype=np.int32)
        self.n = need
        return first

    def trimmed(self):
        return self.bounds[: self.n].copy(), self.child[: self.n].copy(), self.count[: self.n].copy()


def build_rbvh(surface: TriangleMesh | PointCloud, quality: str | Quality = "Q2", *, split: str = "sah",
               hybrid: bool = True, rays: str = "coherent", bins: int = 16, max_depth: int = 64,
               curvature_deg: float | None = None, cone_tolerance: float = 0.01,
               overlap: float = 0.0, mip_levels: int = 1, layout: str = "wide") -> SurfaceIndex:
    """Build a rasterized BVH (hybrid by default) over a triangle mesh or a point cloud.

    Parameters
    ----------
    surface : TriangleMesh or PointCloud
        Point clouds need normals (``load_points`` estimates them for files
        without); they are splatted as discs.
    quality : {"Q0", "Q1", "Q2", "Q3", "Q4"} or Quality
        Q0 finest (rho 2M, alpha 0.85, phi 45 deg) to Q4 coarsest (32k, 0.65, 65).
    split : {"sah", "median"}
        The RBVH SAH over binned centroids, or the spatial median of the longest
        axis. Either way a node holding exactly two connected components is split
        between them (the object split).
    hybrid : bool
        Let subtrees that do not suit height fields become exact triangle BVHs.
    rays : {"coherent", "incoherent"}
        Which of the paper's optimal-resolution fits caps the tile resolution.
    bins : int
        SAH bins per axis.
    max_depth : int
        Nodes this deep stop splitting (as triangle leaves, or tiles at the cap).
    curvature_deg : float, optional
        A vertex is curved when an adjacent face normal deviates more than this
        from its normal (default ``phi / 2``).
    cone_tolerance : float
        Share of a node's area whose normals may leave the cone of half-angle
        ``phi`` (rasterized anyway, nearest surface wins). Scanned meshes have a
        few noisy normals nearly everywhere; an exact cone test (0) splits them
        into many tiny tiles.
    overlap : float
        Primitives within ``overlap`` times the node's extent of a split plane go
        to both children (the paper uses 0.05, :data:`OVERLAP`). The default 0
        is measured better here (``sparsecast bench``: about 3x fewer tiles,
        2-3x faster, fewer silhouette errors): every leaf already holds whole
        triangles, so adjacent tiles meet edge to edge, and the dilated border
        closes the sub-texel gap between them.
    mip_levels : int
        Atlas levels, each half the resolution of the one before (1: none). Camera
        rays pick the level whose texel matches their pixel footprint.
    layout : {"wide", "binary"}
        Traversal layout: the binary tree collapsed to 4-wide nodes
        (:mod:`sparsecast.surface.rbvh_wide`: fewer, vectorised node visits; the
        default), or the binary tree itself. Same leaves, same hits.

    Returns
    -------
    SurfaceIndex
        ``kind == "rbvh"``; ``stats()`` reports nodes, tiles, texels, bytes and
        the build phases.
    """
    q = _resolve_quality(quality)
    if split not in ("sah", "median"):
        raise ParameterError(f"split: expected 'sah' or 'median', got {split!r}")
    if not 2 <= bins <= 256:
        raise ParameterError(f"bins: expected 2..256, got {bins}")
    if not 0.0 <= cone_tolerance < 0.5:
        raise ParameterError(f"cone_tolerance: expected a share in [0, 0.5), got {cone_tolerance}")
    if not 0.0 <= overlap <= 0.5:
        raise ParameterError(f"overlap: expected a share of the node extent in [0, 0.5], got {overlap}")
    if not 1 <= mip_levels <= 8:
        raise ParameterError(f"mip_levels: expected 1..8, got {mip_levels}")
    if not 4 <= max_depth <= 256:
        raise ParameterError(f"max_depth: expected 4..256, got {max_depth}")
    if layout not in LAYOUTS:
        raise ParameterError(f"layout: expected one of {', '.join(LAYOUTS)}, got {layout!r}")
    r_cap = resolution_cap(q.rho, rays)
    is_mesh = isinstance(surface, TriangleMesh)
    if not is_mesh:
        if not isinstance(surface, PointCloud):
            raise ParameterError(f"surface: expected a TriangleMesh or PointCloud, got {type(surface).__name__}")
        if surface.normals is None:
            raise ParameterError(f"surface {surface.source!r}: a point cloud needs normals to be rasterized into tiles "
                                 "(sparsecast.surface.normals.estimate_normals)")
    hybrid = hybrid and is_mesh
    phases: dict[str, float] = {}
    t_all = time.perf_counter()
    tic = time.perf_counter()
    prims = _mesh_prims(surface, curvature_deg or q.phi_deg / 2) if is_mesh else _point_prims(surface)
    m = len(prims.parea)
    rho_w = q.rho / float(prims.parea.sum())  # texels per world area
    cos_phi = math.cos(math.radians(q.phi_deg))
    phases["prims"] = time.perf_counter() - tic

    nodes = _Nodes(max(16, 2 * m // 64))
    refs = np.arange(m, dtype=np.int32)
    f_start = np.zeros(1, np.int64)
    f_count = np.full(1, m, np.int64)
    f_node = np.zeros(1, np.int32)
    f_tri = np.zeros(1, bool)
    tile_nodes, tile_normals, tile_res, tile_refs = [], [], [], []
    tri_refs: list[np.ndarray] = []
    n_tri = 0
    depth = 0
    level_stats: list[tuple[int, int]] = []
    for key in ("reduce", "decide", "split", "compact"):
        phases[key] = 0.0
    while len(f_start):
        depth += 1
        level_stats.append((len(f_start), int(f_count.sum())))
        tic = time.perf_counter()
        st = K.node_stats(refs, f_start, f_count, prims.pmin, prims.pmax, prims.pcent, prims.pnorm,
                          prims.parea, prims.pcurvy, prims.pcomp, cos_phi)
        phases["reduce"] += time.perf_counter() - tic
        tic = time.perf_counter()
        area = st[:, K.S_AREA]
        a_perp = np.linalg.norm(st[:, K.S_NX:K.S_NZ + 1], axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            res = np.sqrt(rho_w * area**2 / a_perp)
            flat = a_perp / area > q.alpha
            in_cone = st[:, K.S_OUT_AREA] <= cone_tolerance * area
        tile_ok = ~f_tri & in_cone & flat & (res <= r_cap) & (area > 0)
        at_limit = depth >= max_depth
        if hybrid:
            curvy = st[:, K.S_CURVY] / np.maximum(f_count, 1) > HYBRID_CURVY_SHARE
            to_tri = f_tri | (~tile_ok & ((f_count < HYBRID_MIN_TRIANGLES) | curvy))
            tri_leaf = (to_tri & (f_count <= TRI_LEAF)) | (~tile_ok & at_limit)
        else:
            to_tri = np.zeros_like(tile_ok)
            tri_leaf = to_tri
        forced = ~tile_ok & ~tri_leaf & ((f_count <= 1) | at_limit)
        is_tile = tile_ok | forced
        is_split = ~is_tile & ~tri_leaf
        phases["decide"] += time.perf_counter() - tic

        # Leaves of this level.
        if is_tile.any():
            idx = np.flatnonzero(is_tile)
            tile_nodes.append(f_node[idx])
            nrm = st[idx, K.S_NX:K.S_NZ + 1]
            bad = np.linalg.norm(nrm, axis=1) == 0  # forced tile of opposite faces: any axis works
            nrm[bad] = (0.0, 0.0, 1.0)
            tile_normals.append(nrm)
            r = np.where(np.isfinite(res[idx]), res[idx], r_cap)
            tile_res.append(np.clip(np.rint(r), MIN_RES, max(MIN_RES, math.floor(r_cap))).astype(np.int64))
            tile_refs.append((f_start[idx], f_count[idx], refs))
        if tri_leaf.any():
            idx = np.flatnonzero(tri_leaf)
            leaf = f_node[idx]
            nodes.child[leaf] = n_tri + np.concatenate([[0], np.cumsum(f_count[idx])[:-1]])
            nodes.count[leaf] = f_count[idx]
            nodes.bounds[leaf, 0] = st[idx, K.S_LO:K.S_LO + 3]
            nodes.bounds[leaf, 1] = st[idx, K.S_HI:K.S_HI + 3]
            tri_refs.append(refs[_ranges(f_start[idx], f_count[idx])])
            n_tri += int(f_count[idx].sum())
        if not is_split.any():
            break

        # Split planes, then compaction into the next level's references.
        tic = time.perf_counter()
        idx = np.flatnonzero(is_split)
        s_start, s_count, s_tri = f_start[idx], f_count[idx], to_tri[idx]
        s_st = np.ascontiguousarray(st[idx])
        axis, pos = K.choose_splits(refs, s_start, s_count, s_st, prims.pmin, prims.pmax, prims.pcent,
                                    prims.parea, split == "sah", bins)
        mode = np.where(s_tri | (overlap == 0.0), K.SPLIT_PLANE, K.SPLIT_DUP).astype(np.int32)
        mode[(s_st[:, K.S_COMP_2] == 1.0) & ~s_tri] = K.SPLIT_OBJECT
        extent = s_st[np.arange(len(idx)), K.S_HI + axis] - s_st[np.arange(len(idx)), K.S_LO + axis]
        band = overlap * extent
        comp_hi = s_st[:, K.S_COMP_HI].astype(np.int32)
        phases["split"] += time.perf_counter() - tic
        tic = time.perf_counter()
        nl, nr, mode = K.partition_counts(refs, s_start, s_count, mode, axis, pos, band, comp_hi,
                                          prims.pmin, prims.pmax, prims.pcent, prims.pcomp)
        sizes = np.stack([nl, nr], 1).ravel()
        child_start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        new_refs = np.empty(int(sizes.sum()), np.int32)
        K.partition_write(refs, s_start, s_count, mode, axis, pos, band, comp_hi, prims.pmin, prims.pmax,
                          prims.pcent, prims.pcomp, new_refs, child_start[0::2].copy(),
                          child_start[1::2].copy())
        first = nodes.alloc_pairs(len(idx))
        nodes.child[f_node[idx]] = first
        nodes.count[f_node[idx]] = 0
        refs = new_refs
        f_start = child_start
        f_count = sizes
        f_node = np.stack([first, first + 1], 1).ravel().astype(np.int32)
        f_tri = np.repeat(s_tri, 2)
        phases["compact"] += time.perf_counter() - tic

    # Rasterize the tile leaves into the atlas.
    tic = time.perf_counter()
    node_bounds, node_child, node_count = nodes.trimmed()
    atlas_arrays = empty_atlas_arrays()
    if tile_nodes:
        t_nodes = np.concatenate(tile_nodes)
        t_refs = np.concatenate([r[_ranges(s, c)] for s, c, r in tile_refs]).astype(np.int32)
        t_count = np.concatenate([c for _, c, _ in tile_refs])
        t_start = np.concatenate([[0], np.cumsum(t_count)[:-1]])
        if is_mesh:
            atlas = build_atlas(np.concatenate(tile_normals), np.concatenate(tile_res), t_start, t_count, t_refs,
                                tris=surface.triangles, faces=surface.faces, vnormals=surface.vertex_normals,
                                levels=mip_levels)
        else:
            atlas = build_atlas(np.concatenate(tile_normals), np.concatenate(tile_res), t_start, t_count, t_refs,
                                points=surface.points, pnormals=surface.normals, radii=np.asarray(surface.radii),
                                levels=mip_levels)
        node_child[t_nodes] = np.arange(len(t_nodes), dtype=np.int32)
        node_count[t_nodes] = TILE_LEAF
        node_bounds[t_nodes] = atlas.boxes
        atlas_arrays = dict(tiles=atlas.tiles, atlas_depth=atlas.depth, atlas_normal=atlas.normal)
    phases["atlas"] = time.perf_counter() - tic
    tic = time.perf_counter()
    K.refit(node_bounds, node_child, node_count)
    phases["refit"] = time.perf_counter() - tic
    wide = None
    if layout == "wide":
        tic = time.perf_counter()
        wide = collapse_binary(node_bounds, node_child, node_count)
        node_bounds = np.zeros((0, 2, 3), np.float32)
        node_child, node_count = np.zeros(0, np.int32), np.zeros(0, np.int32)
        phases["collapse"] = time.perf_counter() - tic
    tri_ids = np.concatenate(tri_refs).astype(np.int32) if tri_refs else np.zeros(0, np.int32)
    if is_mesh:
        tris = np.ascontiguousarray(surface.triangles[tri_ids], dtype=np.float32)
        # Shading normals of the leaf triangles only, re-indexed (not the whole mesh's).
        used, local = np.unique(surface.faces[tri_ids], return_inverse=True)
        faces = local.reshape(-1, 3).astype(np.int32)
        vnormals = surface.vertex_normals[used].astype(np.float32)
    else:
        tris = np.zeros((0, 3, 3), np.float32)
        faces, vnormals = np.zeros((0, 3), np.int32), np.zeros((0, 3), np.float32)
    build = {"build_ms": (time.perf_counter() - t_all) * 1e3,
             **{f"phase_{k}_ms": v * 1e3 for k, v in phases.items()},
             "quality": q.__dict__ | {"name": quality if isinstance(quality, str) else None},
             "split": split, "hybrid": hybrid, "overlap": overlap, "rays": rays, "resolution_cap": r_cap,
             "layout": layout,
             "refs_per_level": [c for _, c in level_stats]}
    return SurfaceIndex(
        kind="rbvh", source=surface, node_bounds=node_bounds, node_child=node_child, node_count=node_count,
        tris=tris, tri_face=tri_ids, faces=faces, vnormals=vnormals, depth=depth, build=build,
        mip_levels=mip_levels if tile_nodes else 1, wide_rbvh=wide, **atlas_arrays)
