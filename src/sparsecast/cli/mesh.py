"""``sparsecast render-mesh``: ray cast a triangle mesh or point cloud with the BVH or the RBVH."""

from __future__ import annotations

import time
import warnings
from pathlib import Path
from typing import Annotated, Optional

import typer

from .._util.checks import one_of
from ..errors import ParameterError
from .._util.atomic import check_output
from ..image import IMAGE_SUFFIXES
from ..kernel_cache import compile_note, compile_seconds
from .app import AzimuthOpt, ElevationOpt, OutputOpt, ProjectionOpt, SizeOpt, UpOpt, ZoomOpt, app, out, warn
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
    splits: Annotated[float, typer.Option(help="--index bvh: spatial splits before the build, up to this many extra references per triangle (0..4; 1 pays on meshes of long, thin triangles, such as CAD tessellations).")] = 0.0,
    mode: Annotated[str, typer.Option(help="shaded, depth or normal.")] = "shaded",
    azimuth: AzimuthOpt = 30.0,
    elevation: ElevationOpt = 20.0,
    projection: ProjectionOpt = "perspective",
    zoom: ZoomOpt = 1.0,
    size: SizeOpt = "512x512",
    up: UpOpt = None,
    y_up: Annotated[Optional[bool], typer.Option("--y-up/--z-up", hidden=True, help="Deprecated: --up y / --up z.")] = None,
    drop_degenerate: Annotated[bool, typer.Option("--drop-degenerate", help="Remove zero-area triangles (a mesh may keep up to 0.1 % of them, with a warning; more are an error without this).")] = False,
    points: Annotated[bool, typer.Option("--points", help="Read the file as a point cloud (discs), even a mesh's vertices; a PLY without faces is one anyway.")] = False,
    radius: Annotated[Optional[float], typer.Option(help="Point clouds: disc radius (default from the point spacing).")] = None,
    output: OutputOpt = Path("sparsecast-mesh.png"),
) -> None:
    """Render a triangle mesh (or point cloud) with an exact BVH or a rasterized BVH."""
    from ..camera import Camera
    from ..axes import axis_vector
    from ..surface import PointCloud, build_bvh, build_rbvh, render_surface
    from ..surface.mesh import orient, orient_points, tiny_points, warmup_mesh
    from ..surface.render import MODES

    one_of(index, "--index", INDICES)
    one_of(mode, "--mode", MODES)
    if y_up is not None:  # the deprecated spelling of --up y / --up z
        if up is not None:
            raise ParameterError(f"--y-up/--z-up: give the up axis once, as --up (got --up {up} too)")
        up = "y" if y_up else "z"
    up = up or "z"
    axis_vector(up, "--up")
    width, height = parse_size(size)
    check_output(output, "-o", IMAGE_SUFFIXES)  # before any work
    t0 = time.perf_counter()
    surface, dropped = _load_surface(file, points, radius, drop_degenerate)
    if isinstance(surface, PointCloud):
        surface = orient_points(surface, up)
        what = (f"{len(surface.points)} points" + ("" if points else " (no faces: rendered as points)")
                + f", disc radius {float(surface.radii[0]):.4g}"
                + (f", normals estimated (PCA, {NORMALS_K} neighbours)" if surface.normals_estimated else ""))
    else:
        if radius is not None:
            raise ParameterError(f"--radius: applies to point clouds; {file.name} is a mesh "
                                 f"of {surface.n_triangles} triangles (--points reads its vertices)")
        surface = orient(surface, up)
        what = f"{surface.n_triangles} triangles" + (f" after dropping {dropped} degenerate" if drop_degenerate else "")
    if not 0.0 <= splits <= 4.0:
        raise ParameterError(f"--splits: expected extra references per triangle in 0..4, got {splits}")
    if splits and index != "bvh":
        raise ParameterError(f"--splits: spatial splits are an option of the exact BVH (--index bvh), "
                             f"got --index {index}")
    if splits and isinstance(surface, PointCloud):
        raise ParameterError(f"--splits: spatial splits cut triangles; {file.name} is rendered as points")
    build = (lambda m: build_rbvh(m, quality)) if index == "rbvh" else (lambda m: build_bvh(m, splits=splits))
    # Compile the build kernels on a tiny surface of the same kind first (Numba caches
    # them on disk), so the build time printed below is the build's, not the first
    # run's JIT compilation; render_surface does the same for its kernel.
    c0 = compile_seconds()
    build(tiny_points() if isinstance(surface, PointCloud) else warmup_mesh())
    idx = build(surface)
    cam = Camera.orbit(surface, azimuth, elevation, projection=projection, zoom=zoom)  # type: ignore[arg-type]
    img = render_surface(idx, cam, width, height, mode=mode)
    img.save(output)
    s, st = img.stats, idx.stats()
    note = compile_note(compile_seconds() - c0)
    out.print(
        f"wrote {output} ({width}x{height}, {file.name}: {what}, index {index}"
        + (f" {quality}, {st['tiles']} tiles" if index == "rbvh" else "")
        + (f", spatial splits: {st['references']} references" if splits else "")
        + f", {st['nodes']} nodes, {st['bytes'] / 2**20:.1f} MiB; build {st['build_ms']:.0f} ms, "
        f"render {s['ms']:.0f} ms, {s['mrays_s']:.1f} Mrays/s; " + (f"{note}, " if note else "")
        + f"{time.perf_counter() - t0:.1f} s total)"
    )


def _load_surface(file: Path, points: bool, radius, drop: bool):
    """The point cloud (``--points``, or a file without faces) or mesh in ``file``, with
    the loader's warnings on stderr (one ``warning:`` line each) and its advice in the
    command line's words (``--drop-degenerate``, not the API's argument); returns it and
    how many degenerate triangles were dropped."""
    from ..io.meshes import load_points, load_surface
    from ..surface.mesh import DegenerateFacesError, DegenerateFacesWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            mesh = (load_points(file, radius=radius) if points
                    else load_surface(file, radius=radius, drop_degenerate=drop))
        except DegenerateFacesError as exc:
            raise DegenerateFacesError(exc.source, exc.count, exc.total, exc.first, "pass --drop-degenerate to remove them") from None
    dropped = 0
    for w in caught:
        m = w.message
        if isinstance(m, DegenerateFacesWarning):
            if m.dropped:
                dropped = m.count  # said on the output line
            else:
                warn(f"{file}: {m.count} of {m.total} triangles are degenerate (zero area); kept (no ray "
                     f"hits them); --drop-degenerate removes them")
        else:
            warn(str(m))
    return mesh, dropped
