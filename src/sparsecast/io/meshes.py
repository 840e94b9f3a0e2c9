"""Mesh and point-cloud readers (PLY, OBJ, STL, GLB through trimesh; points from PLY/npy).

Every error names the file: a missing or unreadable file is a
:class:`~sparsecast.errors.FileFormatError`; readable files with unusable content
(empty, NaN, more than 0.1 % degenerate triangles) raise
:class:`~sparsecast.surface.mesh.MeshDataError`. What still ray casts correctly loads
with a :class:`~sparsecast.surface.mesh.MeshWarning`: a few degenerate (zero-area)
triangles, which no ray hits, and non-manifold edges (shared by more than two triangles).
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from .._util.checks import positive_float
from ..errors import FileFormatError
from ..surface.mesh import DegenerateFacesWarning, MeshDataError, MeshWarning, PointCloud, TriangleMesh
from .files import require_regular_file
from .npy import read_npy_array

__all__ = ["load_mesh", "load_points", "MESH_SUFFIXES"]

MESH_SUFFIXES = (".ply", ".obj", ".stl", ".glb", ".gltf", ".off")


def _trimesh_load(path: Path):
    import trimesh

    require_regular_file(path, "mesh file")
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise FileFormatError(f"{str(path)!r}: unsupported suffix {suffix!r}; expected one of {', '.join(MESH_SUFFIXES)}")
    try:
        # process=False: keep the file's vertices and faces as they are (no merging),
        # so errors refer to what the file holds.
        return trimesh.load(path, process=False)
    except Exception as exc:  # trimesh raises many kinds for corrupt files
        raise FileFormatError(f"{str(path)!r}: cannot read as {suffix[1:].upper()}: {exc}") from exc


def _non_manifold_edges(faces: np.ndarray) -> int:
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int((counts > 2).sum())


def load_mesh(path: str | os.PathLike, *, drop_degenerate: bool = False) -> TriangleMesh:
    """Read a triangle mesh; scenes (GLB, multi-object OBJ) are merged into one mesh.

    Parameters
    ----------
    path : path-like
        ``.ply .obj .stl .glb .gltf .off``.
    drop_degenerate : bool
        Remove the zero-area triangles (with a :class:`DegenerateFacesWarning` that says
        how many). Without it, a mesh keeps up to 0.1 % of them
        (:data:`~sparsecast.surface.mesh.DEGENERATE_FRACTION`; with a warning) and more
        raise.

    Warns
    -----
    DegenerateFacesWarning
        Degenerate triangles kept or dropped (``count``, ``total``, ``dropped``).
    MeshWarning
        Non-manifold edges.

    Raises
    ------
    FileFormatError
        Missing, unsupported or unreadable file; a file without triangles.
    MeshDataError
        NaN/Inf vertices, bad indices; more than 0.1 % degenerate triangles
        (:class:`~sparsecast.surface.mesh.DegenerateFacesError`).
    """
    import trimesh

    p = Path(path)
    obj = _trimesh_load(p)
    if isinstance(obj, trimesh.Scene):
        geoms = [g for g in obj.dump() if isinstance(g, trimesh.Trimesh)] if obj.geometry else []
        obj = trimesh.util.concatenate(geoms) if geoms else None
    if not isinstance(obj, trimesh.Trimesh) or len(obj.faces) == 0:
        kind = type(obj).__name__ if obj is not None else "an empty scene"
        raise FileFormatError(f"{str(p)!r}: holds no triangles (found {kind}); expected a triangle mesh"
                              + (" (use load_points for point clouds)" if kind == "PointCloud" else ""))
    v, f = np.asarray(obj.vertices), np.asarray(obj.faces)
    if drop_degenerate:
        mesh, dropped = TriangleMesh.cleaned(v, f, source=str(p))
        if dropped:
            warnings.warn(DegenerateFacesWarning(
                f"{str(p)!r}: dropped {dropped} degenerate (zero-area) triangles of {len(f)}",
                dropped, len(f), dropped=True), stacklevel=2)
    else:
        mesh = TriangleMesh(v, f, source=str(p))
        kept = mesh.degenerate_faces.size
        if kept:
            warnings.warn(DegenerateFacesWarning(
                f"{str(p)!r}: {kept} of {len(f)} triangles are degenerate (zero area; first is face "
                f"{int(mesh.degenerate_faces[0])}); kept, no ray hits them (drop_degenerate=True removes them)",
                kept, len(f), dropped=False), stacklevel=2)
    nm = _non_manifold_edges(mesh.faces)
    if nm:
        warnings.warn(MeshWarning(
            f"{str(p)!r}: {nm} non-manifold edges (shared by more than two triangles); "
            "the mesh is still ray cast as given"), stacklevel=2)
    return mesh


def load_points(path: str | os.PathLike, *, radius: float | None = None) -> PointCloud:
    """Read a point cloud from ``.ply`` (vertices, optional normals) or ``.npy``.

    A ``.npy`` file holds an ``(n, 3)`` array of points or ``(n, 6)`` of points
    and normals. A ``.ply`` mesh is read as its vertices (with vertex normals).
    ``radius`` (positive) is the disc radius of every point.
    """
    if radius is not None:
        radius = positive_float(radius, "radius")
    p = Path(path)
    suffix = p.suffix.lower()
    normals = None
    if suffix == ".npy":
        a = read_npy_array(p, "NumPy .npy points")
        if a.dtype.names is not None or a.dtype.kind not in "biuf":
            raise MeshDataError(f"{str(p)!r}: array of dtype {a.dtype}; expected numbers")
        if a.ndim != 2 or a.shape[1] not in (3, 6):
            raise MeshDataError(f"{str(p)!r}: expected an (n, 3) or (n, 6) array, got shape {a.shape}")
        pts, normals = a[:, :3], (a[:, 3:] if a.shape[1] == 6 else None)
    elif suffix == ".ply":
        import trimesh

        obj = _trimesh_load(p)
        pts = np.asarray(getattr(obj, "vertices", np.empty((0, 3))))
        if isinstance(obj, trimesh.Trimesh) and len(obj.faces):
            normals = np.asarray(obj.vertex_normals)
        else:
            attrs = getattr(obj, "metadata", {}).get("_ply_raw", {}).get("vertex", {}).get("data")
            if attrs is not None and all(k in attrs.dtype.names for k in ("nx", "ny", "nz")):
                normals = np.stack([attrs["nx"], attrs["ny"], attrs["nz"]], 1).astype(np.float64)
    else:
        raise FileFormatError(f"{str(p)!r}: unsupported point-cloud suffix {suffix!r}; expected .ply or .npy")
    return PointCloud(pts, normals, radius, source=str(p))
