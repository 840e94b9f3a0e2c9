"""``sparsecast render-mesh``: ray cast a triangle mesh or point cloud with the BVH or the RBVH."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from .._util.checks import one_of
from ..errors import ParameterError
from .._util.atomic import check_output
from ..image import IMAGE_SUFFIXES
from .app import AzimuthOpt, ElevationOpt, OutputOpt, ProjectionOpt, SizeOpt, ZoomOpt, app, out
from .parse import parse_size
from ..surface.normals import DEFAULT_K as NORMALS_K

__all__ = ["render_mesh", "INDICES"]

#: the surface indices render-mesh offers
INDICES = ("rbvh", "bvh")


@app.command("render-mesh")
def render_mesh(
    file: Annotated[Path, typer.Argument(help="Mesh (.ply .obj .stl .glb .off) or point cloud (a .ply without faces; .npy with --points).")],
    index: Annotated[str, typer.Option(help="rbvh (approximate, height-field tiles) or bvh (exact triangles or discs).")] = "rbvh",
    quality: Annotated[str, typer.Option(help="RBVH quality preset Q0 (finest) .. Q4 (coarsest).")] = "Q2",
    mode: Annotated[str, typer.Option(help="shaded, depth or normal.")] = "shaded",
    azimuth: AzimuthOpt = 30.0,
    elevation: ElevationOpt = 20.0,
    projection: ProjectionOpt = "perspective",
    zoom: ZoomOpt = 1.0,
    size: SizeOpt = "512x512",
    y_up: Annotated[bool, typer.Option("--y-up/--z-up", help="The file's up axis (scanned meshes are usually y-up).")] = False,
    points: Annotated[bool, typer.Option("--points", help="Read the file as a point cloud (discs), even a mesh's vertices; a PLY without faces is one anyway.")] = False,
    radius: Annotated[Optional[float], typer.Option(help="Point clouds: disc radius (default from the point spacing).")] = None,
    output: OutputOpt = Path("sparsecast-mesh.png"),
) -> None:
    """Render a triangle mesh (or point cloud) with an exact BVH or a rasterized BVH."""
    from ..camera import Camera
    from ..io.meshes import load_points, load_surface
    from ..surface import PointCloud, build_bvh, build_rbvh, render_surface
    from ..surface.mesh import icosphere, orient_points, z_up
    from ..surface.render import MODES

    one_of(index, "--index", INDICES)
    one_of(mode, "--mode", MODES)
    width, height = parse_size(size)
    check_output(output, "-o", IMAGE_SUFFIXES)  # before any work
    t0 = time.perf_counter()
    surface = load_points(file, radius=radius) if points else load_surface(file, radius=radius)
    if isinstance(surface, PointCloud):
        if y_up:
            surface = orient_points(surface, "y")
        what = (f"{len(surface.points)} points" + ("" if points else " (no faces: rendered as points)")
                + f", disc radius {float(surface.radii[0]):.4g}"
                + (f", normals estimated (PCA, {NORMALS_K} neighbours)" if surface.normals_estimated else ""))
    else:
        if radius is not None:
            raise ParameterError(f"--radius: applies to point clouds; {file.name} is a mesh "
                                 f"of {surface.n_triangles} triangles (--points reads its vertices)")
        if y_up:
            surface = z_up(surface)
        what = f"{surface.n_triangles} triangles"
    build = (lambda m: build_rbvh(m, quality)) if index == "rbvh" else build_bvh
    # Compile the build kernels on a tiny mesh first (Numba caches them on disk), so the
    # build time printed below is the build's, not the first run's JIT compilation.
    t_jit = time.perf_counter()
    tiny = icosphere(3)
    build(tiny if not isinstance(surface, PointCloud) else PointCloud(tiny.vertices, tiny.vertices, 0.1, "warm-up"))
    jit_ms = (time.perf_counter() - t_jit) * 1e3
    idx = build(surface)
    cam = Camera.orbit(surface, azimuth, elevation, projection=projection, zoom=zoom)  # type: ignore[arg-type]
    img = render_surface(idx, cam, width, height, mode=mode)
    img.save(output)
    s, st = img.stats, idx.stats()
    out.print(
        f"wrote {output} ({width}x{height}, {file.name}: {what}, index {index}"
        + (f" {quality}, {st['tiles']} tiles" if index == "rbvh" else "")
        + f", {st['nodes']} nodes, {st['bytes'] / 2**20:.1f} MiB; build {st['build_ms']:.0f} ms, "
        f"render {s['ms']:.0f} ms, {s['mrays_s']:.1f} Mrays/s; {time.perf_counter() - t0:.1f} s total"
        + (f", of which {jit_ms / 1e3:.1f} s compiling the build kernels on first use)" if jit_ms > 1000 else ")")
    )
