"""Surface containers: :class:`TriangleMesh` and :class:`PointCloud`, validated once.

Both keep float64 coordinates for building and hand float32 copies to the kernels.
They expose ``center`` and ``diagonal`` so :meth:`sparsecast.Camera.orbit` frames
them exactly as it frames a volume.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..axes import UP_AXES, up_rotation
from ..errors import SparsecastError
from ..neighbours import typical_spacing

__all__ = ["MeshDataError", "DegenerateFacesError", "MeshWarning", "DegenerateFacesWarning", "DEGENERATE_FRACTION",
           "TriangleMesh", "PointCloud", "icosphere", "subdivide", "grid_plane", "box_mesh", "orient", "z_up",
           "UP_AXES", "orient_points", "default_disc_radius", "tiny_points", "warmup_mesh"]

#: A mesh may keep up to this fraction of its faces degenerate (zero area): 0.1 %. Scanned
#: and converted meshes often carry a handful (the Stanford dragon: 111 of 871,414); they
#: cannot be hit and are harmless, while more than this suggests a broken file (a wrong
#: face layout, merged vertices).
DEGENERATE_FRACTION = 1e-3


class MeshDataError(SparsecastError):
    """Mesh or point data is unusable: empty, NaN/Inf, out-of-range or degenerate faces."""


class DegenerateFacesError(MeshDataError):
    """More than :data:`DEGENERATE_FRACTION` of a mesh's faces have zero area.

    ``count``, ``total`` and ``first`` (the first such face) let a caller word its own
    remedy (the command line names ``--drop-degenerate``); :meth:`describe` is the shared
    part of the message.
    """

    def __init__(self, source: str, count: int, total: int, first: int, remedy: str) -> None:
        self.source, self.count, self.total, self.first = source, count, total, first
        super().__init__(f"{self.describe()}; {remedy}")

    def describe(self) -> str:
        return (f"{self.source}: {self.count} of {self.total} triangles are degenerate (zero area; first is face "
                f"{self.first}), more than the {100 * DEGENERATE_FRACTION:g} % a mesh may keep")


class MeshWarning(UserWarning):
    """A mesh loads and renders, but something in it deserves a look."""


class DegenerateFacesWarning(MeshWarning):
    """A mesh has degenerate (zero-area) faces: ``count`` of ``total``; ``dropped`` says
    whether loading removed them (``drop_degenerate=True``) or kept them (few enough)."""

    def __init__(self, message: str, count: int, total: int, dropped: bool) -> None:
        super().__init__(message)
        self.count, self.total, self.dropped = count, total, dropped


def _check_points(v: np.ndarray, what: str, source: str) -> np.ndarray:
    v = np.ascontiguousarray(v, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise MeshDataError(f"{source}: expected {what} of shape (n, 3), got {v.shape}")
    if v.shape[0] == 0:
        raise MeshDataError(f"{source}: has no {what} (empty); expected at least one")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise MeshDataError(
            f"{source}: {int(bad.sum())} of {len(v)} {what} contain NaN or Inf "
            f"(first at row {int(np.argmax(bad))}); expected finite coordinates"
        )
    return v


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """An indexed triangle mesh.

    Parameters
    ----------
    vertices : (n, 3) array_like of float
    faces : (m, 3) array_like of int
        Vertex indices. At most :data:`DEGENERATE_FRACTION` (0.1 %) of the faces may
        have zero area (:attr:`degenerate_faces`); the indices never hit them.
    source : str
        Name used in error messages (the file, or a description).

    Raises
    ------
    MeshDataError
        Empty input, NaN/Inf vertices, indices out of range.
    DegenerateFacesError
        More than 0.1 % of the faces have zero area (``TriangleMesh.cleaned`` drops
        them first if that is what you want).
    """

    vertices: np.ndarray
    faces: np.ndarray
    source: str = "mesh"
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        v = _check_points(self.vertices, "vertices", self.source)
        f = np.asarray(self.faces)
        if f.ndim != 2 or f.shape[1] != 3:
            raise MeshDataError(f"{self.source}: expected faces of shape (m, 3), got {f.shape}")
        if f.shape[0] == 0:
            raise MeshDataError(f"{self.source}: has no faces (empty); expected at least one triangle")
        if not np.issubdtype(f.dtype, np.integer):
            raise MeshDataError(f"{self.source}: expected integer face indices, got dtype {f.dtype}")
        if f.min() < 0 or f.max() >= len(v):
            raise MeshDataError(
                f"{self.source}: face indices span [{f.min()}, {f.max()}]; expected 0..{len(v) - 1}"
            )
        f = np.ascontiguousarray(f, dtype=np.int32)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        degenerate = self.degenerate_faces
        if degenerate.size > DEGENERATE_FRACTION * len(f):
            raise DegenerateFacesError(self.source, int(degenerate.size), len(f), int(degenerate[0]),
                                       "load with drop_degenerate=True to remove them")

    @classmethod
    def cleaned(cls, vertices, faces, source: str = "mesh") -> tuple["TriangleMesh", int]:
        """The mesh without its zero-area faces, and how many were dropped."""
        v = _check_points(vertices, "vertices", source)
        f = np.asarray(faces, dtype=np.int64)
        if f.ndim == 2 and f.shape[1] == 3 and f.size and f.min() >= 0 and f.max() < len(v):
            keep = ~_degenerate(_face_areas(v, f), v)
            return cls(v, f[keep], source), int((~keep).sum())
        return cls(v, f, source), 0

    # -- geometry ----------------------------------------------------------
    def _cached(self, key, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[0])

    @property
    def triangles(self) -> np.ndarray:
        """(m, 3, 3) float64 corner coordinates."""
        return self._cached("tris", lambda: self.vertices[self.faces])

    @property
    def face_areas(self) -> np.ndarray:
        """(m,) float64 triangle areas."""
        return self._cached("areas", lambda: _face_areas(self.vertices, self.faces))

    @property
    def degenerate_faces(self) -> np.ndarray:
        """Indices of the zero-area faces (area at most 1e-14 of the squared bounding-box
        diagonal: collinear corners, repeated vertices), ascending; usually empty."""
        return self._cached("degenerate", lambda: np.flatnonzero(_degenerate(self.face_areas, self.vertices)))

    @property
    def face_normals(self) -> np.ndarray:
        """(m, 3) unit geometric normals (right-hand rule on the vertex order)."""

        def make():
            t = self.triangles
            n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

        return self._cached("fn", make)

    @property
    def vertex_normals(self) -> np.ndarray:
        """(n, 3) area-weighted unit vertex normals (smooth shading)."""

        def make():
            w = self.face_normals * self.face_areas[:, None]
            idx = self.faces.ravel()
            # bincount sums per vertex much faster than np.add.at
            acc = np.stack([np.bincount(idx, np.repeat(w[:, a], 3), minlength=len(self.vertices))
                            for a in range(3)], axis=1)
            n = np.linalg.norm(acc, axis=1, keepdims=True)
            return np.where(n > 0, acc / np.maximum(n, 1e-300), 0.0)

        return self._cached("vn", make)

    @property
    def area(self) -> float:
        return float(self.face_areas.sum())

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) min and max corner."""
        return np.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @property
    def bbox_area(self) -> float:
        e = np.ptp(self.vertices, axis=0)
        return float(e @ e)

    @property
    def center(self) -> np.ndarray:
        return self.bounds.mean(axis=0)

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(np.ptp(self.vertices, axis=0)))

    @property
    def nbytes(self) -> int:
        return int(self.vertices.nbytes + self.faces.nbytes)

    def __repr__(self) -> str:
        return f"<TriangleMesh {self.source!r}: {len(self.vertices)} vertices, {self.n_triangles} triangles>"


def _degenerate(areas: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Mask of zero-area faces: relative to the bounding box, so the test does not depend
    on the mesh's units."""
    e = np.ptp(v, axis=0)
    return areas <= 1e-14 * max(float(e @ e), 1e-300)


def _face_areas(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    t = v[f]
    return 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)


#: neighbour whose median distance is the default disc radius (see default_disc_radius)
DISC_RADIUS_NEIGHBOUR = 4


def default_disc_radius(points: np.ndarray) -> float:
    """Disc radius that closes a sampled surface: the median distance to the 4th neighbour.

    On a surface sampled with spacing ``s`` the 4th neighbour lies about ``s`` away,
    and discs of radius ``s`` overlap their neighbours (``s / sqrt(2)`` already covers
    a square grid), so the splats leave no holes without blurring detail. A median
    follows the bulk of the scan, not its outliers; the box of a scan says little
    about its sampling (twice the radius on the bunny scan bun000). Fewer than 5
    points: the spacing of ``n`` points spread over the box's faces.
    """
    p = np.asarray(points, dtype=np.float64)
    r = typical_spacing(p, DISC_RADIUS_NEIGHBOUR) if len(p) > DISC_RADIUS_NEIGHBOUR else 0.0
    if r <= 0.0:
        ext = np.ptp(p, axis=0)
        r = float(np.sqrt(2.0 * (ext[0] * ext[1] + ext[1] * ext[2] + ext[0] * ext[2]) / len(p)))
    return max(r, 1e-9)


@dataclass(frozen=True, eq=False)
class PointCloud:
    """Oriented points, rendered as discs (splats) of radius ``radii``.

    Parameters
    ----------
    points : (n, 3) array_like
    normals : (n, 3) array_like, optional
        Unit normals; the discs are oriented by them, so both
        :func:`sparsecast.surface.build_rbvh` and :func:`sparsecast.surface.build_bvh`
        require them (:func:`sparsecast.surface.normals.estimate_normals` makes them
        for a cloud without; :func:`sparsecast.io.meshes.load_points` does so itself).
    radii : float or (n,) array_like, optional
        Disc radii; default :func:`default_disc_radius` (from the point spacing).
    source : str
        Name used in messages.
    normals_estimated : bool
        True when ``normals`` were estimated from the points, not read.
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    radii: np.ndarray | float | None = None
    source: str = "points"
    normals_estimated: bool = False

    def __post_init__(self) -> None:
        p = _check_points(self.points, "points", self.source)
        object.__setattr__(self, "points", p)
        if self.normals is not None:
            n = _check_points(self.normals, "normals", self.source)
            if n.shape != p.shape:
                raise MeshDataError(f"{self.source}: normals shape {n.shape} differs from points {p.shape}")
            ln = np.linalg.norm(n, axis=1, keepdims=True)
            if (ln == 0).any():
                raise MeshDataError(f"{self.source}: {int((ln == 0).sum())} normals are zero; expected unit normals")
            object.__setattr__(self, "normals", n / ln)
        if self.radii is None:
            r = np.full(len(p), default_disc_radius(p))
        else:
            r = np.broadcast_to(np.asarray(self.radii, dtype=np.float64), (len(p),)).copy()
            if not (np.isfinite(r).all() and (r > 0).all()):
                raise MeshDataError(f"{self.source}: radii must be positive and finite")
        object.__setattr__(self, "radii", r)

    @property
    def bounds(self) -> np.ndarray:
        r = float(np.max(self.radii))
        return np.stack([self.points.min(axis=0) - r, self.points.max(axis=0) + r])

    @property
    def center(self) -> np.ndarray:
        return self.bounds.mean(axis=0)

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(np.ptp(self.bounds, axis=0)))

    @property
    def area(self) -> float:
        """Total disc area (the surface the splats cover)."""
        return float(np.pi * np.sum(np.asarray(self.radii) ** 2))

    def __repr__(self) -> str:
        return f"<PointCloud {self.source!r}: {len(self.points)} points>"


# -- generated meshes (tests, benchmarks) -------------------------------------
def subdivide(mesh: TriangleMesh, levels: int = 1) -> TriangleMesh:
    """Midpoint subdivision: every level splits each triangle into four (same surface)."""
    v, f = mesh.vertices, mesh.faces.astype(np.int64)
    for _ in range(levels):
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        key = np.sort(edges, axis=1)
        uniq, inv = np.unique(key, axis=0, return_inverse=True)
        mid = len(v) + inv.reshape(3, -1).T  # (m, 3): midpoints of edges 01, 12, 20
        v = np.concatenate([v, 0.5 * (v[uniq[:, 0]] + v[uniq[:, 1]])])
        a, b, c = f[:, 0], f[:, 1], f[:, 2]
        m01, m12, m20 = mid[:, 0], mid[:, 1], mid[:, 2]
        f = np.concatenate([
            np.stack([a, m01, m20], 1), np.stack([m01, b, m12], 1),
            np.stack([m20, m12, c], 1), np.stack([m01, m12, m20], 1),
        ])
    return TriangleMesh(v, f, f"{mesh.source} (subdivided x{levels})")


def icosphere(subdivisions: int = 3, radius: float = 1.0) -> TriangleMesh:
    """A unit-ish sphere: an icosahedron subdivided and projected onto the sphere."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return TriangleMesh(np.asarray(s.vertices), np.asarray(s.faces), f"icosphere({subdivisions})")


def warmup_mesh() -> TriangleMesh:
    """A small mesh that takes every path of the surface builds: a sphere beside a small flat plate.

    Two components (the RBVH's object split), curved triangles that stay exact leaves
    and a plate that becomes height-field tiles at every quality preset (a sphere
    alone makes no tile at Q0, and the atlas kernels then compiled inside the first
    real build). 1,500 triangles: milliseconds to build once compiled.
    """
    sphere = icosphere(3)
    # Small: a tile's texel count grows with its world-space area (rho texels per unit
    # area), and Q0's resolution cap refuses tiles bigger than about 1e-3 units^2.
    plate = grid_plane(16, size=0.05, z=-1.5)
    v = np.concatenate([sphere.vertices, plate.vertices])
    f = np.concatenate([sphere.faces, plate.faces + len(sphere.vertices)])
    return TriangleMesh(v, f, "warm-up sphere and plate")


def tiny_points(n: int = 1500, radius: float = 1.0) -> PointCloud:
    """``n`` oriented points evenly spread on a sphere (a Fibonacci lattice), normals outward.

    Small enough to build in milliseconds once compiled; the CLI and
    :func:`sparsecast.compile_kernels` build it to compile the point-cloud kernels.
    """
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5.0 ** 0.5) * i
    r = np.sqrt(1.0 - z * z)
    unit = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    return PointCloud(radius * unit, unit, source=f"sphere points({n})")


def grid_plane(n: int = 8, size: float = 1.0, z: float = 0.0) -> TriangleMesh:
    """A flat square ``[0, size]^2`` at height ``z`` split into ``2 n^2`` triangles."""
    g = np.linspace(0.0, size, n + 1)
    xx, yy = np.meshgrid(g, g)
    v = np.stack([xx.ravel(), yy.ravel(), np.full(xx.size, z)], 1)
    i = np.arange(n)
    a = (i[:, None] * (n + 1) + i[None, :]).ravel()
    f = np.concatenate([np.stack([a, a + 1, a + n + 2], 1), np.stack([a, a + n + 2, a + n + 1], 1)])
    return TriangleMesh(v, f, f"plane({n})")


def box_mesh(lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0), n: int = 1) -> TriangleMesh:
    """An axis-aligned closed box, each face split into ``2 n^2`` triangles."""
    import trimesh

    b = trimesh.creation.box(bounds=np.array([lo, hi], dtype=np.float64))
    return subdivide(TriangleMesh(np.asarray(b.vertices), np.asarray(b.faces), "box"), max(0, int(np.log2(max(n, 1)))))


def orient(mesh: TriangleMesh, up: str) -> TriangleMesh:
    """The mesh rotated so that its axis ``up`` (``"x"``, ``"-y"``, ...) becomes +z, the up
    axis of :meth:`sparsecast.Camera.orbit`.

    A proper rotation (det +1, :func:`sparsecast.axes.up_rotation`): the winding and so the
    face normals turn with the vertices, nothing is mirrored. For ``up="y"`` it maps
    ``(x, y, z) -> (x, -z, y)``, so the front of a y-up mesh (+z, the OpenGL convention)
    faces the orbit camera at azimuth 0. ``up="z"`` returns ``mesh`` itself.

    Parameters
    ----------
    mesh : TriangleMesh
    up : str
        One of :data:`sparsecast.axes.UP_AXES`.
    """
    r = up_rotation(up)
    if np.array_equal(r, np.eye(3)):
        return mesh
    # A signed permutation: the rotated coordinates are exact copies (no rounding).
    return TriangleMesh(mesh.vertices @ r.T, mesh.faces, mesh.source)


def z_up(mesh: TriangleMesh) -> TriangleMesh:
    """Rotate a y-up mesh (most scanned meshes: bunny, beast) so +z is up: ``orient(mesh, "y")``."""
    return orient(mesh, "y")


def orient_points(cloud: PointCloud, up: str) -> PointCloud:
    """Rotate ``cloud`` (points and normals) so that its ``up`` axis becomes +z, as
    :meth:`sparsecast.Camera.orbit` expects (``"y"`` for most scans; ``"z"``: unchanged).

    Parameters
    ----------
    cloud : PointCloud
    up : {"x", "y", "z", "-x", "-y", "-z"}

    Returns
    -------
    PointCloud
        The same radii, source and ``normals_estimated``.
    """
    r = up_rotation(up)  # the rotation of orient(): a y-up mesh and cloud of one scan line up
    normals = None if cloud.normals is None else cloud.normals @ r.T
    return PointCloud(cloud.points @ r.T, normals, cloud.radii, cloud.source, cloud.normals_estimated)
