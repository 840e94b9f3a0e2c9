"""The exact reference: a binned-SAH triangle BVH (Aila & Laine's baseline in the RBVH paper)."""

from __future__ import annotations

import time

import numpy as np

from ..errors import ParameterError
from ._bvh_build_kernels import build_binned_sah
from .index import SurfaceIndex, empty_atlas_arrays
from .mesh import TriangleMesh

__all__ = ["build_bvh", "triangle_bvh_arrays"]


def triangle_bvh_arrays(tris: np.ndarray, max_leaf: int = 4, bins: int = 16):
    """Binned-SAH BVH over ``tris`` (k, 3, 3).

    Returns ``node_bounds, node_child, node_count, order, depth``; leaf ranges in
    ``node_child`` index the reordered triangles ``tris[order]``.
    """
    bmin = tris.min(axis=1)
    bmax = tris.max(axis=1)
    cent = 0.5 * (bmin + bmax)
    return build_binned_sah(bmin, bmax, cent, max_leaf, bins)


def build_bvh(mesh: TriangleMesh, *, max_leaf: int = 4, bins: int = 16) -> SurfaceIndex:
    """Exact triangle BVH of ``mesh`` (binned SAH, leaves of at most ``max_leaf`` triangles).

    Parameters
    ----------
    mesh : TriangleMesh
    max_leaf : int
        1..32 triangles per leaf.
    bins : int
        SAH bins per node, 2..256.
    """
    if not isinstance(mesh, TriangleMesh):
        raise ParameterError(f"mesh: expected a TriangleMesh (see sparsecast.io.load_mesh), got {type(mesh).__name__}")
    if not 1 <= max_leaf <= 32:
        raise ParameterError(f"max_leaf: expected 1..32 triangles, got {max_leaf}")
    if not 2 <= bins <= 256:
        raise ParameterError(f"bins: expected 2..256, got {bins}")
    t0 = time.perf_counter()
    tris = mesh.triangles.astype(np.float32)
    t1 = time.perf_counter()
    nb, nchild, ncount, order, depth = triangle_bvh_arrays(tris, max_leaf, bins)
    t2 = time.perf_counter()
    index = SurfaceIndex(
        kind="bvh", source=mesh, node_bounds=nb, node_child=nchild, node_count=ncount,
        tris=np.ascontiguousarray(tris[order]), tri_face=order.astype(np.int32),
        faces=np.ascontiguousarray(mesh.faces[order]), vnormals=mesh.vertex_normals.astype(np.float32),
        depth=int(depth), **empty_atlas_arrays(),
        build={"build_ms": (time.perf_counter() - t0) * 1e3,
               "phase_prepare_ms": (t1 - t0) * 1e3, "phase_sah_ms": (t2 - t1) * 1e3,
               "max_leaf": max_leaf, "bins": bins},
    )
    return index
