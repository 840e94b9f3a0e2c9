"""Mesh and point-cloud readers (PLY, OBJ, STL, GLB through trimesh; points from PLY/npy).

:func:`load_surface` reads either: a file with vertices but no faces is a point cloud.

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
from ..surface.normals import DEFAULT_K, estimate_normals
from .files import require_regular_file
from .npy import read_npy_array

__all__ = ["load_mesh", "load_points", "load_surface", "MESH_SUFFIXES"]

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


def load_points(path: str | os.PathLike, *, radius: float | None = None,
                normals_k: int = DEFAULT_K) -> PointCloud:
    """Read a point cloud from ``.ply`` (vertices, optional normals) or ``.npy``.

    A ``.npy`` file holds an ``(n, 3)`` array of points or ``(n, 6)`` of points
    and normals. A ``.ply`` mesh is read as its vertices (with vertex normals).
    ``radius`` (positive) is the disc radius of every point (default: from the
    point spacing, :func:`~sparsecast.surface.mesh.default_disc_radius`).

    A file without normals (a raw range scan, particles) gets normals estimated
    by PCA over each point's ``normals_k`` nearest neighbours
    (:func:`~sparsecast.surface.normals.estimate_normals`, oriented away from the
    centroid); the cloud's ``normals_estimated`` is then True.
    """
    if radius is not None:
        radius = positive_float(radius, "radius")
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".npy":
        a = read_npy_array(p, "NumPy .npy points")
        if a.dtype.names is not None or a.dtype.kind not in "biuf":
            raise MeshDataError(f"{str(p)!r}: array of dtype {a.dtype}; expected numbers")
        if a.ndim != 2 or a.shape[1] not in (3, 6):
            raise MeshDataError(f"{str(p)!r}: expected an (n, 3) or (n, 6) array, got shape {a.shape}")
        pts, normals = a[:, :3], (a[:, 3:] if a.shape[1] == 6 else None)
    elif suffix == ".ply":
        pts, normals = _ply_points(_trimesh_load(p))
    else:
        raise FileFormatError(f"{str(p)!r}: unsupported point-cloud suffix {suffix!r}; expected .ply or .npy")
    return _cloud(pts, normals, radius, str(p), normals_k)


def load_surface(path: str | os.PathLike, *, radius: float | None = None,
                 normals_k: int = DEFAULT_K, drop_degenerate: bool = False) -> TriangleMesh | PointCloud:
    """A triangle mesh, or a point cloud when the file holds vertices but no faces.

    What ``sparsecast render-mesh`` reads: a PLY of points (a range scan, a particle
    dump) is rendered as discs rather than refused. ``radius`` and ``normals_k``
    apply to point clouds only (see :func:`load_points`); meshes load as
    :func:`load_mesh` loads them (``drop_degenerate`` too).
    """
    import trimesh

    p = Path(path)
    obj = _trimesh_load(p)
    if isinstance(obj, trimesh.PointCloud):
        pts, normals = _ply_points(obj)
        return _cloud(pts, normals, positive_float(radius, "radius") if radius is not None else None,
                      str(p), normals_k)
    return load_mesh(p, drop_degenerate=drop_degenerate)


def _ply_points(obj) -> tuple[np.ndarray, np.ndarray | None]:
    import trimesh

    pts = np.asarray(getattr(obj, "vertices", np.empty((0, 3))))
    normals = None
    if isinstance(obj, trimesh.Trimesh) and len(obj.faces):
        normals = np.asarray(obj.vertex_normals)
    else:
        attrs = getattr(obj, "metadata", {}).get("_ply_raw", {}).get("vertex", {}).get("data")
        # binary PLY: a structured array; ASCII PLY: a dict of columns
        names = attrs.keys() if isinstance(attrs, dict) else (getattr(getattr(attrs, "dtype", None), "names", None) or ())
        if all(k in names for k in ("nx", "ny", "nz")):
            normals = np.stack([np.asarray(attrs[k], np.float64).reshape(-1) for k in ("nx", "ny", "nz")], 1)
    return pts, normals


def _cloud(pts, normals, radius, source: str, normals_k: int) -> PointCloud:
    estimated = normals is None
    if estimated:
        # Validate the points first: NaN or an empty file is the error to report,
        # not what PCA makes of it.
        pts = PointCloud(pts, None, 1.0, source).points
        if len(pts) < 3:
            raise MeshDataError(f"{source}: {len(pts)} points and no normals; estimating normals needs at least 3")
        normals = estimate_normals(pts, normals_k)
    return PointCloud(pts, normals, radius, source=source, normals_estimated=estimated)
