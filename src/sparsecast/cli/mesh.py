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
from ..kernel_cache import compile_note, compile_seconds
from .app import AzimuthOpt, ElevationOpt, OutputOpt, ProjectionOpt, SizeOpt, ZoomOpt, app, out
from .parse import parse_size

__all__ = ["render_mesh", "INDICES"]

#: the surface indices render-mesh offers
INDICES = ("rbvh", "bvh")


@app.command("render-mesh")
def render_mesh(
    file: Annotated[Path, typer.Argument(help="Mesh (.ply .obj .stl .glb .off) or, with --points, a point cloud (.ply .npy).")],
    index: Annotated[str, typer.Option(help="rbvh (approximate, height-field tiles) or bvh (exact triangles).")] = "rbvh",
    quality: Annotated[str, typer.Option(help="RBVH quality preset Q0 (finest) .. Q4 (coarsest).")] = "Q2",
    mode: Annotated[str, typer.Option(help="shaded, depth or normal.")] = "shaded",
    azimuth: AzimuthOpt = 30.0,
    elevation: ElevationOpt = 20.0,
    projection: ProjectionOpt = "perspective",
    zoom: ZoomOpt = 1.0,
    size: SizeOpt = "512x512",
    y_up: Annotated[bool, typer.Option("--y-up/--z-up", help="The file's up axis (scanned meshes are usually y-up).")] = False,
    points: Annotated[bool, typer.Option("--points", help="Read the file as a point cloud (splatted discs; needs --index rbvh).")] = False,
    radius: Annotated[Optional[float], typer.Option(help="Point clouds: disc radius (default from the point spacing).")] = None,
    output: OutputOpt = Path("sparsecast-mesh.png"),
) -> None:
    """Render a triangle mesh (or point cloud) with an exact BVH or a rasterized BVH."""
    from ..camera import Camera
    from ..io.meshes import load_mesh, load_points
    from ..surface import build_bvh, build_rbvh, render_surface
    from ..surface.mesh import tiny_points, warmup_mesh, z_up
    from ..surface.render import MODES

    one_of(index, "--index", INDICES)
    one_of(mode, "--mode", MODES)
    if points and index != "rbvh":
        raise ParameterError("--points: point clouds are rendered with --index rbvh only")
    width, height = parse_size(size)
    check_output(output, "-o", IMAGE_SUFFIXES)  # before any work
    t0 = time.perf_counter()
    if points:
        surface = load_points(file, radius=radius)
        if y_up:
            raise ParameterError("--y-up: only meshes can be rotated; pass z-up points")
        what = f"{len(surface.points)} points"
    else:
        surface = load_mesh(file)
        if y_up:
            surface = z_up(surface)
        what = f"{surface.n_triangles} triangles"
    build = (lambda m: build_rbvh(m, quality)) if index == "rbvh" else build_bvh
    # Compile the build kernels on a tiny surface of the same kind first (Numba caches
    # them on disk), so the build time printed below is the build's, not the first
    # run's JIT compilation; render_surface does the same for its kernel.
    c0 = compile_seconds()
    build(tiny_points() if points else warmup_mesh())
    idx = build(surface)
    cam = Camera.orbit(surface, azimuth, elevation, projection=projection, zoom=zoom)  # type: ignore[arg-type]
    img = render_surface(idx, cam, width, height, mode=mode)
    img.save(output)
    s, st = img.stats, idx.stats()
    note = compile_note(compile_seconds() - c0)
    out.print(
        f"wrote {output} ({width}x{height}, {file.name}: {what}, index {index}"
        + (f" {quality}, {st['tiles']} tiles" if index == "rbvh" else "")
        + f", {st['nodes']} nodes, {st['bytes'] / 2**20:.1f} MiB; build {st['build_ms']:.0f} ms, "
        f"render {s['ms']:.0f} ms, {s['mrays_s']:.1f} Mrays/s; " + (f"{note}, " if note else "")
        + f"{time.perf_counter() - t0:.1f} s total)"
    )
