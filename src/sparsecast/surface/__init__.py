"""Surface ray casting: an exact triangle BVH and the rasterized BVH (RBVH).

>>> from sparsecast.io.meshes import load_mesh             # doctest: +SKIP
>>> from sparsecast import surface, Camera                 # doctest: +SKIP
>>> mesh = load_mesh("bunny.ply")                          # doctest: +SKIP
>>> rbvh = surface.build_rbvh(mesh, quality="Q2")          # doctest: +SKIP
>>> img = surface.render_surface(rbvh, Camera.orbit(mesh, 30, 20), 512, 512)  # doctest: +SKIP
>>> hits = surface.raycast(rbvh, origins, directions)      # doctest: +SKIP
"""

from .bvh import build_bvh
from .index import Hits, RayCast, SurfaceIndex, raycast
from .mesh import MeshDataError, PointCloud, TriangleMesh
from .rbvh import QUALITY, Quality, build_rbvh
from .render import render_surface

__all__ = ["build_bvh", "build_rbvh", "raycast", "RayCast", "render_surface", "Hits", "SurfaceIndex",
           "TriangleMesh", "PointCloud", "MeshDataError", "QUALITY", "Quality"]
