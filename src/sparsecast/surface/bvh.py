"""The exact reference: a binned-SAH BVH over triangles (Aila & Laine's baseline in the
RBVH paper) or over the oriented discs of a point cloud.

Both go through the one parallel binned-SAH builder over primitive boxes
(:mod:`.sah`), then flatten its build layout into the traversal layout; only the boxes and the leaf primitives differ. A disc
of centre ``c``, unit normal ``n`` and radius ``r`` spans ``c +- r sqrt(1 - n_a^2)``
along axis ``a`` (its tight box: a disc facing the axis is flat along it), so the
tree culls a flat scan as well as a triangle mesh of it.
"""

from __future__ import annotations

import time

import numpy as np

from .._util.checks import as_float
from ..errors import ParameterError
from ._bvh_kernels import disc_leaf_code
from .index import SurfaceIndex, empty_atlas_arrays
from .mesh import PointCloud, TriangleMesh
from .presplit import presplit_refs
from .sah import BuildTree, build_sah
from .wide import collapse_tree

__all__ = ["build_bvh", "LAYOUTS", "triangle_tree", "triangle_bvh_arrays", "disc_boxes"]


def triangle_tree(tris: np.ndarray, max_leaf: int = 4, bins: int = 16, splits: float = 0.0) -> BuildTree:
    """Binned-SAH BVH over ``tris`` (k, 3, 3) in the build layout; ``ids`` orders the leaf triangles.

    ``splits`` > 0 builds over :func:`.presplit.presplit_refs`'s references (that many
    extra references per triangle, at most): a triangle may then lie in several leaves.
    """
    if splits > 0.0:
        lo, hi, prims = presplit_refs(tris, splits)
        return build_sah(lo, hi, max_leaf, bins, prims=prims)
    # Corner by corner: NumPy reduces the short middle axis of (k, 3, 3) slowly.
    lo = np.minimum(np.minimum(tris[:, 0], tris[:, 1]), tris[:, 2])
    hi = np.maximum(np.maximum(tris[:, 0], tris[:, 1]), tris[:, 2])
    return build_sah(lo, hi, max_leaf, bins)


def triangle_bvh_arrays(tris: np.ndarray, max_leaf: int = 4, bins: int = 16):
    """Binned-SAH BVH over ``tris`` (k, 3, 3), in the binary traversal layout.

    Returns ``node_bounds, node_child, node_count, order, depth``; leaf ranges in
    ``node_child`` index the reordered triangles ``tris[order]``.
    """
    tree = triangle_tree(tris, max_leaf, bins)
    return (*tree.flatten(), tree.ids, tree.depth)


def disc_boxes(centers: np.ndarray, normals: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tight boxes ``(lo, hi)``, each (k, 3), of discs with unit ``normals`` (k, 3) and ``radii`` (k,)."""
    half = radii[:, None] * np.sqrt(np.clip(1.0 - normals * normals, 0.0, 1.0))
    return centers - half, centers + half


#: traversal layouts of :func:`build_bvh`
LAYOUTS = ("wide", "binary")


def build_bvh(surface: TriangleMesh | PointCloud, *, max_leaf: int = 4, bins: int = 16,
              layout: str | None = None, splits: float = 0.0) -> SurfaceIndex:
    """Exact BVH of a triangle mesh, or of a point cloud's discs (binned SAH).

    Parameters
    ----------
    surface : TriangleMesh or PointCloud
        A point cloud is ray cast as discs of its radii, oriented by its normals
        (required: :func:`sparsecast.surface.normals.estimate_normals` makes them).
    max_leaf : int
        1..32 primitives per leaf.
    bins : int
        SAH bins per axis, 2..256.
    layout : {"wide", "binary"}, optional
        Traversal layout: the 4-wide BVH (:mod:`sparsecast.surface.wide`; the
        default for meshes) or the binary one (the default, and the only one, for
        point clouds). Both come from the same build tree.
    splits : float
        Spatial splits before the build (:mod:`sparsecast.surface.presplit`, Karras &
        Aila 2013): up to ``splits`` extra box references per triangle, 0..4, given to
        the triangles whose boxes hold the most empty space; 0 (the default): one box
        a triangle. Meshes only.
    """
    if not isinstance(surface, (TriangleMesh, PointCloud)):
        raise ParameterError(f"mesh: expected a TriangleMesh or PointCloud (see sparsecast.io.meshes.load_mesh, "
                             f"load_points), got {type(surface).__name__}")
    if not 1 <= max_leaf <= 32:
        raise ParameterError(f"max_leaf: expected 1..32 primitives, got {max_leaf}")
    if not 2 <= bins <= 256:
        raise ParameterError(f"bins: expected 2..256, got {bins}")
    if layout is not None and layout not in LAYOUTS:
        raise ParameterError(f"layout: expected one of {', '.join(LAYOUTS)}, got {layout!r}")
    splits = as_float(splits, "splits", 0.0, 4.0, expected="extra references per triangle in 0..4")
    if isinstance(surface, PointCloud):
        if splits:
            raise ParameterError(f"splits: spatial splits cut triangles; a point cloud ({surface.source!r}) "
                                 "is ray cast as discs (splits=0)")
        if layout == "wide":
            raise ParameterError(f"layout: the wide BVH holds triangles; a point cloud ({surface.source!r}) "
                                 "is ray cast as discs in the binary layout (layout='binary')")
        return _build_disc_bvh(surface, max_leaf, bins)
    mesh = surface
    t0 = time.perf_counter()
    tris = mesh.triangles.astype(np.float32)
    t1 = time.perf_counter()
    tree = triangle_tree(tris, max_leaf, bins, float(splits))
    t2 = time.perf_counter()
    vnormals = mesh.vertex_normals.astype(np.float32)
    if layout == "binary":
        (nb, nchild, ncount), order = tree.flatten(), tree.ids
        arrays = dict(node_bounds=nb, node_child=nchild, node_count=ncount,
                      tris=np.ascontiguousarray(tris[order]), tri_face=order,
                      faces=np.ascontiguousarray(mesh.faces[order]), depth=tree.depth)
    else:
        wide = collapse_tree(tree, tris)
        # The wide leaves name mesh faces: shading reads the mesh's own corner indices.
        arrays = dict(node_bounds=np.zeros((0, 2, 3), np.float32), node_child=np.zeros(0, np.int32),
                      node_count=np.zeros(0, np.int32), tris=np.zeros((0, 3, 3), np.float32),
                      tri_face=np.zeros(0, np.int32), faces=np.ascontiguousarray(mesh.faces, dtype=np.int32),
                      depth=tree.depth, wide=wide)
    t3 = time.perf_counter()
    return SurfaceIndex(
        kind="bvh", source=mesh, vnormals=vnormals, **arrays, **empty_atlas_arrays(),
        build={"build_ms": (time.perf_counter() - t0) * 1e3,
               "phase_prepare_ms": (t1 - t0) * 1e3, "phase_sah_ms": (t2 - t1) * 1e3,
               "phase_flatten_ms": (t3 - t2) * 1e3, "max_leaf": max_leaf, "bins": bins,
               "threads": tree.threads, "layout": layout or "wide", "splits": float(splits),
               "references": int(len(tree.ids))},
    )


def _build_disc_bvh(cloud: PointCloud, max_leaf: int, bins: int) -> SurfaceIndex:
    if cloud.normals is None:
        raise ParameterError(f"surface {cloud.source!r}: a point cloud needs normals to orient its discs "
                             "(sparsecast.surface.normals.estimate_normals)")
    t0 = time.perf_counter()
    radii = np.asarray(cloud.radii, np.float64)
    lo, hi = disc_boxes(cloud.points, cloud.normals, radii)
    # float32 boxes, as the traversal stores them: rounded outwards so that no disc
    # pokes out of its box (a ray could then miss a leaf that holds its hit)
    lo32 = np.nextafter(lo.astype(np.float32), np.float32(-np.inf))
    hi32 = np.nextafter(hi.astype(np.float32), np.float32(np.inf))
    t1 = time.perf_counter()
    tree = build_sah(lo32, hi32, max_leaf, bins)
    (nb, nchild, ncount), order, depth = tree.flatten(), tree.ids, tree.depth
    t2 = time.perf_counter()
    leaf = ncount > 0
    ncount[leaf] = disc_leaf_code(ncount[leaf])
    discs = np.concatenate([cloud.points, cloud.normals, radii[:, None]], axis=1)[order].astype(np.float32)
    return SurfaceIndex(
        kind="bvh", source=cloud, node_bounds=nb, node_child=nchild, node_count=ncount,
        tris=np.zeros((0, 3, 3), np.float32), tri_face=np.zeros(0, np.int32),
        faces=np.zeros((0, 3), np.int32), vnormals=np.zeros((0, 3), np.float32),
        depth=int(depth), **empty_atlas_arrays(),
        discs=np.ascontiguousarray(discs), disc_point=order.astype(np.int32),
        build={"build_ms": (time.perf_counter() - t0) * 1e3,
               "phase_prepare_ms": (t1 - t0) * 1e3, "phase_sah_ms": (t2 - t1) * 1e3,
               "max_leaf": max_leaf, "bins": bins, "threads": tree.threads},
    )
