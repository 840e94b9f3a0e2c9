"""Benchmark section ``surface``: the RBVH paper's Tables 1-4 on our meshes.

Per mesh (the shared ``bunny`` and ``beast``, and ``bunny-1m``: the bunny
midpoint-subdivided twice to 1.1 M triangles, same surface; ``sphere-1m`` stands
in when the shared data is absent; opt-in: ``turbine`` (the shared 199 k turbine
blade scan), ``bunny-4m``, ``sphere-1m``, ``slivers`` (100 k long, thin triangles at
random, generated: where spatial splits pay), and the
RBVH's own regime of 4-10 M triangles, built in memory from the shared dragon:
``dragon`` (871 k), ``dragon-3.5m`` (subdivided once: the same surface, four times
the triangles) and ``dragons-7m`` (eight dragons side by side, each turned about
the vertical: 7 M triangles of distinct surface)):

- ``phase="load"``: reading (and generating) the mesh;
- ``phase="build"`` (Tables 1-2): the exact BVH (``bvh``: the 4-wide layout;
  ``bvh-binary``: the same build tree in the binary layout; ``bvh-splits``: the 4-wide
  BVH built over spatially split references, :data:`BENCH_SPLITS` extra per triangle
  at most) and the RBVH at Q0-Q4 (SAH
  splits, 4-wide layout) plus Q2 with median splits, Q2 in the binary layout
  (``rbvh-Q2-binary``) and Q2 with 3 mip levels: build ms, nodes, tiles, texels,
  bytes of nodes / triangles / atlas, and ``mem_ratio`` = RBVH bytes / (BVH nodes +
  triangles) from the same run;
- ``phase="render"`` (Table 3, primary rays) and ``phase="render_diffuse"``
  (Table 4, one cosine-distributed diffuse ray per primary hit, the same rays for
  every method): ms, ``mrays_s``, ``cpu_ms`` and ``mrays_cpu_s`` (rays per
  CPU-second of all threads: the fair figure beside a peer that traces on one
  thread), ``threads``, ``speedup`` over the BVH in the same run; for
  the RBVH also ``psnr`` of the shaded image against the BVH's, mean/max depth
  error in % of the bounding-box diagonal, and the share of pixels whose hit/miss
  differs;
- the Embree peer through Open3D's ``RaycastingScene`` when it imports (a
  ``phase="skipped"`` record with the reason otherwise); its ``build`` is the
  triangle copy plus the first cast of the primary rays (``copy_ms`` +
  ``first_cast_ms``), since Open3D builds Embree's BVH lazily in the first cast;
  its renders record the same wall and CPU figures (``cores_busy`` = CPU / wall
  says how many threads it kept busy).

Primary and diffuse casts are timed in interleaved rounds (:func:`.timing.interleaved`:
a warm-up round, then every method and Embree in turn per round), each render record
with the median, its runs, min / max / MAD and the median CPU ms.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable

import numba
import numpy as np

from ..camera import Camera
from ..io.meshes import load_mesh
from ..surface import RayCast, build_bvh, build_rbvh
from ..surface.index import SurfaceIndex
from ..surface.mesh import TriangleMesh, icosphere, subdivide, z_up
from ..surface.render import cast_camera, shade
from ..surface.secondary import cosine_directions, facing
from .images import psnr
from .shared_data import find_shared_data
from .timing import Frame, Runs, interleaved, median_ms

__all__ = ["run", "MESHES", "DEFAULT_DATASETS", "QUALITIES"]

QUALITIES = ("Q0", "Q1", "Q2", "Q3", "Q4")
#: extra references per triangle of the ``bvh-splits`` method
BENCH_SPLITS = 1.0
VIEW = (30.0, 20.0)


def _shared(file: str) -> Callable[[], TriangleMesh]:
    def load() -> TriangleMesh:
        root = find_shared_data()
        if root is None or not (root / file).is_file():
            raise FileNotFoundError(f"{file}: not in the shared data folder")
        return z_up(load_mesh(root / file))

    return load


def side_by_side(mesh: TriangleMesh, nx: int, ny: int, seed: int = 3) -> TriangleMesh:
    """``nx * ny`` copies of ``mesh`` on a grid in the xy plane, each turned about z by a random angle.

    Copies are spaced by the mesh's largest horizontal extent plus 15 %, so they
    never overlap whatever their turn; the turns make every copy present a
    different side to the camera (a scene of distinct surfaces, not one repeated view).
    """
    v = mesh.vertices - mesh.vertices.mean(axis=0)
    pitch = 1.15 * float(np.linalg.norm(np.ptp(v[:, :2], axis=0)))
    angles = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, nx * ny)
    verts, faces = [], []
    for k, a in enumerate(angles):
        c, s = np.cos(a), np.sin(a)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        verts.append(v @ rot.T + np.array([(k % nx) * pitch, (k // nx) * pitch, 0.0]))
        faces.append(mesh.faces + k * len(v))
    return TriangleMesh(np.concatenate(verts), np.concatenate(faces), f"{mesh.source} ({nx}x{ny} copies)")


def slivers(n: int = 100_000, length: float = 0.8, width: float = 0.01, seed: int = 0) -> TriangleMesh:
    """``n`` long, thin triangles (``length`` by ``width``) at random places and turns in
    the cube ``[-1, 1]^3``: boxes far larger than their triangles, as in CAD tessellations,
    where spatial splits (``build_bvh(splits=...)``) pay."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(-1.0, 1.0, (n, 3))
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = rng.normal(size=(n, 3))
    w -= (w * u).sum(axis=1, keepdims=True) * u
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    v = np.stack([c - 0.5 * length * u, c + 0.5 * length * u, c + width * w], axis=1)
    return TriangleMesh(v.reshape(-1, 3), np.arange(3 * n).reshape(n, 3), f"slivers-{n}")


#: name -> (loader, needs shared data)
MESHES: dict[str, tuple[Callable[[], TriangleMesh], bool]] = {
    "bunny": (_shared("stanford_bunny.ply"), True),
    "beast": (_shared("beast.ply"), True),
    "bunny-1m": (lambda: subdivide(_shared("stanford_bunny.ply")(), 2), True),
    "bunny-4m": (lambda: subdivide(_shared("stanford_bunny.ply")(), 3), True),
    "sphere-1m": (lambda: icosphere(8), False),
    "slivers": (slivers, False),
    "turbine": (_shared("turbine_blade_199k.ply"), True),
    "dragon": (_shared("stanford_dragon_871k.ply"), True),
    "dragon-3.5m": (lambda: subdivide(_shared("stanford_dragon_871k.ply")(), 1), True),
    "dragons-7m": (lambda: side_by_side(_shared("stanford_dragon_871k.ply")(), 4, 2), True),
}
DEFAULT_DATASETS = ("bunny", "beast", "bunny-1m")
#: the names ``sparsecast bench --suite surface --dataset NAME`` takes
DATASET_NAMES = tuple(MESHES)


def _diffuse_rays(hits, cam: Camera, width: int, height: int, eps: float, seed: int = 7):
    """One cosine-weighted hemisphere ray per primary hit, leaving the side the camera sees."""
    o, d = cam.rays(width, height)
    hit = np.isfinite(hits.t)
    n = facing(hits.normals[hit], d[hit])
    p = o[hit] + hits.t[hit][:, None] * d[hit]
    dirs = cosine_directions(n, np.random.default_rng(seed))
    return np.ascontiguousarray(p + eps * n), np.ascontiguousarray(dirs)


def _cast(index: SurfaceIndex, o: np.ndarray, d: np.ndarray) -> Callable[[], object]:
    """The traversal kernel alone on rays ``o + t d`` (checks and output arrays set up once)."""
    return RayCast(index, o, d).run


def _rates(rays: int, ms: float, cpu_ms: float) -> dict:
    """Rays per second (wall) and per CPU-second, and the threads our kernels ran on."""
    return {"mrays_s": rays / ms / 1e3, "cpu_ms": cpu_ms, "mrays_cpu_s": rays / max(cpu_ms, 1e-9) / 1e3,
            "threads": numba.get_num_threads(), "cores_busy": round(cpu_ms / ms, 2) if ms > 0 else None}


def _timing(runs: Runs, rays: int) -> dict:
    """Record fields of one method's interleaved runs: median ms, spread, CPU ms and the rates."""
    f = runs.fields()
    return {**_rates(rays, f["ms"], f["cpu_ms"]), **f}  # cores busy: over all timed runs


def _primary_frame(index: SurfaceIndex, cam: Camera, width: int, height: int) -> Frame:
    """One primary-ray frame; its time is the kernel's (output allocation excluded)."""
    cast_camera(index, cam, 8, 8)  # compile / load outside every round

    def frame():
        h = cast_camera(index, cam, width, height)
        return h, h.ms

    return frame


def _cast_frame(cast: Callable[[], object]) -> Frame:
    cast()  # compile / load outside every round
    return lambda: (cast(), None)


#: Debian packages of the system libraries an Open3D wheel loads and a slim image may lack
_SYSTEM_LIBRARIES = {"libusb-1.0.so.0": "libusb-1.0-0", "libGL.so.1": "libgl1", "libgomp.so.1": "libgomp1",
                     "libEGL.so.1": "libegl1", "libX11.so.6": "libx11-6"}


def _open3d_fix(exc: BaseException) -> str:
    """What to do about Open3D failing to import with ``exc``: install the system library
    its wheel could not load (named in the error), else the package itself."""
    m = re.search(r"([\w.+-]+\.so(?:\.[\d.]+)?): cannot open shared object file", str(exc))
    if m:
        lib = m.group(1)
        package = _SYSTEM_LIBRARIES.get(lib)
        how = f" (Debian/Ubuntu: apt-get install {package})" if package else ""
        return f"open3d is installed but the system library {lib} it loads is missing: install it{how}"
    return "pip install open3d"


def _embree_frames(mesh: TriangleMesh, cam: Camera, width: int, height: int, diffuse,
                   record: Callable[..., None], dataset: str) -> tuple[Frame, Frame] | None:
    """Embree's scene through Open3D, built and recorded (the first cast included), and its
    primary and diffuse frames; None (a ``skipped`` record) when Open3D does not import."""
    try:
        import open3d as o3d  # an optional peer, not a dependency
    except Exception as exc:  # ImportError, or a missing system library behind it
        record(dataset=dataset, method="embree", phase="skipped", ms=None,
               reason=f"open3d (Embree's Python binding here) does not import: {type(exc).__name__}: {exc}; "
                      f"{_open3d_fix(exc)} to time Embree beside the BVH")
        return None
    o, d = cam.rays(width, height)
    prim = o3d.core.Tensor(np.concatenate([o, d], -1).reshape(-1, 6).astype(np.float32))
    sec = o3d.core.Tensor(np.concatenate(diffuse, -1).astype(np.float32))
    # Open3D hands Embree the triangles in add_triangles but commits the scene (builds
    # the BVH) in the first cast: the build figure includes that first cast.
    t0 = time.perf_counter()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)),
                        o3d.core.Tensor(mesh.faces.astype(np.uint32)))
    t1 = time.perf_counter()
    scene.cast_rays(prim)
    t2 = time.perf_counter()
    record(dataset=dataset, method="embree", phase="build", ms=(t2 - t0) * 1e3, copy_ms=(t1 - t0) * 1e3,
           first_cast_ms=(t2 - t1) * 1e3, triangles=mesh.n_triangles)
    return (lambda: (scene.cast_rays(prim), None)), (lambda: (scene.cast_rays(sec), None))


def run(datasets: list[str] | None, *, width: int, height: int, repeat: int, warmup: int,
        record: Callable[..., None]) -> None:
    """Measure every mesh in ``datasets`` (default :data:`DEFAULT_DATASETS`; ``sphere-1m``
    replaces the shared meshes when there is no shared data)."""
    if datasets is None:
        shared = find_shared_data() is not None
        datasets = list(DEFAULT_DATASETS) if shared else ["sphere-1m"]
    for name in datasets:
        if name not in MESHES:
            raise ValueError(f"surface bench: unknown mesh {name!r}; expected one of {', '.join(MESHES)}")
        loader, _ = MESHES[name]
        try:
            t0 = time.perf_counter()
            mesh = loader()
            load_ms = (time.perf_counter() - t0) * 1e3
        except FileNotFoundError as exc:
            record(dataset=name, method="mesh", phase="skipped", ms=None, reason=str(exc))
            continue
        record(dataset=name, method="mesh", phase="load", ms=load_ms, triangles=mesh.n_triangles)
        _bench_mesh(name, mesh, width, height, repeat, warmup, record)


def _bench_mesh(name: str, mesh: TriangleMesh, width: int, height: int, repeat: int, warmup: int,
                record: Callable[..., None]) -> None:
    cam = Camera.orbit(mesh, *VIEW)
    diag = mesh.diagonal
    # Builds get the warm-up too, big meshes included: the first build in a process
    # pays for loading kernels from Numba's cache and first-touch page faults (bunny-1m:
    # 1.8 s cold, 0.65-0.83 s warm). The exact BVH (the 1 s target) always gets the repeats; the RBVH builds of a
    # million triangles take seconds each, so one timed run there.
    big = mesh.n_triangles > 300_000
    builds = max(1, min(repeat, 3))
    build_warm = min(warmup, 1)

    def build_and_record(method: str, make: Callable[[], SurfaceIndex], **extra) -> SurfaceIndex:
        n = 1 if big and method.startswith("rbvh") else builds
        ms, runs, index = median_ms(make, n, build_warm)
        s = index.stats()
        record(dataset=name, method=method, phase="build", ms=ms, ms_runs=runs, bytes=s["bytes"],
               nodes=s["nodes"], depth=s["depth"], tiles=s["tiles"], texels=s["texels"],
               triangle_leaves=s["triangle_leaves"], tile_leaves=s["tile_leaves"],
               bytes_nodes=s["bytes_nodes"], bytes_triangles=s["bytes_triangles"],
               bytes_atlas=s["bytes_atlas"], bytes_shading=s["bytes_shading"],
               phases={k: v for k, v in s.items() if k.startswith("phase_")}, triangles=mesh.n_triangles,
               threads=s.get("threads"), **extra)
        return index

    bvh = build_and_record("bvh", lambda: build_bvh(mesh), layout="wide")
    bvh_bytes = bvh.stats()["bytes_nodes"] + bvh.stats()["bytes_triangles"]
    indices: dict[str, SurfaceIndex] = {"bvh": bvh}
    indices["bvh-binary"] = build_and_record("bvh-binary", lambda: build_bvh(mesh, layout="binary"),
                                             layout="binary")
    # Spatial splits (Karras & Aila's pre-splitting): what they buy on this mesh.
    indices["bvh-splits"] = build_and_record("bvh-splits", lambda: build_bvh(mesh, splits=BENCH_SPLITS),
                                             layout="wide", splits=BENCH_SPLITS)
    for q in QUALITIES:
        idx = build_and_record(f"rbvh-{q}", lambda q=q: build_rbvh(mesh, q), quality=q, split="sah")
        indices[f"rbvh-{q}"] = idx
        _mem_ratio(idx, bvh_bytes, record, name, f"rbvh-{q}")
    med = build_and_record("rbvh-Q2-median", lambda: build_rbvh(mesh, "Q2", split="median"),
                           quality="Q2", split="median")
    indices["rbvh-Q2-median"] = med
    _mem_ratio(med, bvh_bytes, record, name, "rbvh-Q2-median")
    # The binary tree the wide layout is collapsed from: what the 4-wide nodes buy.
    binary = build_and_record("rbvh-Q2-binary", lambda: build_rbvh(mesh, "Q2", layout="binary"),
                              quality="Q2", split="sah", layout="binary")
    indices["rbvh-Q2-binary"] = binary
    _mem_ratio(binary, bvh_bytes, record, name, "rbvh-Q2-binary")
    mip = build_and_record("rbvh-Q2-mip3", lambda: build_rbvh(mesh, "Q2", mip_levels=3), quality="Q2",
                           split="sah", mip_levels=3)
    indices["rbvh-Q2-mip3"] = mip
    _mem_ratio(mip, bvh_bytes, record, name, "rbvh-Q2-mip3")

    # The exact image first: the reference for PSNR and depth errors, and the origin of the
    # diffuse rays every method then casts.
    ref = cast_camera(bvh, cam, width, height)
    dist = float(np.linalg.norm(cam.eye - mesh.center))
    depth_range = (max(dist - diag / 2, 0.0), dist + diag / 2)
    ref_img = shade(ref, cam, "shaded", depth_range)
    diffuse = _diffuse_rays(ref, cam, width, height, eps=1e-4 * diag)
    n_diffuse = len(diffuse[0])
    rays = width * height
    # Every method (and Embree) takes its turn in each round, primary rays and diffuse rays
    # apart (timing.interleaved), so that all share the machine's drifts.
    primary = {m: _primary_frame(idx, cam, width, height) for m, idx in indices.items()}
    secondary = {m: _cast_frame(_cast(idx, *diffuse)) for m, idx in indices.items()}
    embree = _embree_frames(mesh, cam, width, height, diffuse, record, name)
    if embree is not None:
        primary["embree"], secondary["embree"] = embree
    p_runs = interleaved(primary, repeat, warmup)
    d_runs = interleaved(secondary, repeat, warmup)
    ref_ms, ref_d_ms = p_runs["bvh"].fields()["ms"], d_runs["bvh"].fields()["ms"]
    both_ref = np.isfinite(ref.t)
    for method in primary:
        p, d = _timing(p_runs[method], rays), _timing(d_runs[method], n_diffuse)
        extra: dict = {}
        if method == "embree":
            p["threads"] = d["threads"] = None  # Open3D's own choice: cores_busy tells
        else:
            hits = p_runs[method].result
            extra["hits"] = int(np.isfinite(hits.t).sum())
            if method != "bvh":
                both = both_ref & np.isfinite(hits.t)
                err = np.abs(hits.t[both] - ref.t[both]) / diag * 100.0
                extra.update(psnr=psnr(shade(hits, cam, "shaded", depth_range), ref_img),
                             depth_err_mean_pct=float(err.mean()) if err.size else None,
                             depth_err_max_pct=float(err.max()) if err.size else None,
                             hit_mismatch_pct=float(np.mean(np.isfinite(hits.t) != both_ref) * 100.0))
        record(dataset=name, method=method, phase="render", rays=rays, speedup=ref_ms / p["ms"], width=width,
               height=height, view=list(VIEW), **p, **extra)
        record(dataset=name, method=method, phase="render_diffuse", rays=n_diffuse, speedup=ref_d_ms / d["ms"],
               width=width, height=height, view=list(VIEW), **d)


def _mem_ratio(idx: SurfaceIndex, bvh_bytes: int, record, name: str, method: str) -> None:
    s = idx.stats()
    record(dataset=name, method=method, phase="memory", ms=None, bytes=s["bytes"],
           mem_ratio=s["bytes"] / bvh_bytes, atlas_ratio=s["bytes_atlas"] / bvh_bytes)
