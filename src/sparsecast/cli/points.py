"""``sparsecast render-points``: a particle file (a catalogue, a simulation snapshot) to an image."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from .._util.atomic import check_output
from ..errors import FileFormatError, ParameterError
from ..image import IMAGE_SUFFIXES
from ..render.particles import DEFAULT_CMAP, DEFAULT_KAPPA, DEFAULT_OPACITY
from .app import AzimuthOpt, ElevationOpt, OutputOpt, ProjectionOpt, SizeOpt, ZoomOpt, app, out
from .parse import parse_background, parse_pair, parse_size

__all__ = ["render_points", "AUTO_COLOR"]

#: --color-by default: the file's colours if it has any, else the derived log_density
AUTO_COLOR = "auto"


@app.command("render-points")
def render_points(
    file: Annotated[Path, typer.Argument(help="Particles: .ply (vertices), .csv (x,y,z[,radius][,red,green,blue][,other columns]) or .npy.")],
    color_by: Annotated[str, typer.Option(help="Attribute to colour by: a column of the file, or log_density (from the neighbour distances); 'auto': the file's colours if any, else log_density; 'none': the file's colours (white without).")] = AUTO_COLOR,
    cmap: Annotated[str, typer.Option(help="matplotlib colour map for --color-by (inferno, viridis, magma, ...).")] = DEFAULT_CMAP,
    color_range: Annotated[Optional[str], typer.Option(help="Attribute values 'lo,hi' at the colour map's ends (default: 1st and 99th percentile).")] = None,
    radius: Annotated[Optional[float], typer.Option(help="Radius of every particle (default: the file's radii, else the median distance to the 2nd neighbour).")] = None,
    opacity: Annotated[float, typer.Option(help="Opacity at a particle's centre, in (0, 1]; lower shows more of dense cores.")] = DEFAULT_OPACITY,
    kappa: Annotated[float, typer.Option(help="Gaussian falloff: opacity at the rim is opacity * exp(-kappa).")] = DEFAULT_KAPPA,
    up: Annotated[str, typer.Option(help="The file's up axis: x, y, z, -x, -y or -z (turned to +z for the orbit).")] = "z",
    azimuth: AzimuthOpt = 30.0,
    elevation: ElevationOpt = 20.0,
    projection: ProjectionOpt = "perspective",
    zoom: ZoomOpt = 1.0,
    size: SizeOpt = "512x512",
    background: Annotated[str, typer.Option(help="black, white, gray, transparent or 'r,g,b[,a]'.")] = "black",
    output: OutputOpt = Path("sparsecast-points.png"),
) -> None:
    """Render particles as Gaussian spheres through a BIH, coloured by an attribute."""
    from .._util.checks import positive_float
    from ..camera import Camera
    from ..elements import DENSITY_NEIGHBOURS, RADIUS_NEIGHBOURS, ParticleSet
    from ..index.bih import ParticleBIH
    from ..io.particles import load_particles
    from ..render.particles import render_particles
    from ..axes import up_rotation

    width, height = parse_size(size)
    rotation = up_rotation(up)
    bg = parse_background(background)
    vrange = parse_pair(color_range, "--color-range") if color_range is not None else None
    if radius is not None:
        radius = positive_float(radius, "--radius")
    check_output(output, "-o", IMAGE_SUFFIXES)  # before any work
    t0 = time.perf_counter()
    ps = load_particles(file)
    if len(ps) == 0:
        raise FileFormatError(f"{str(file)!r}: holds no particles; expected at least one")
    estimated = ps.radius_estimated and radius is None
    if radius is not None or up.strip().lower() != "z":
        ps = ParticleSet(ps.centers @ rotation.T, ps.radii if radius is None else radius,
                         ps.colors if ps.has_colors else None, name=ps.name, attributes=ps.attributes)
    if color_by == AUTO_COLOR:
        attr = None if ps.has_colors else "log_density"
    else:
        attr = None if color_by == "none" else color_by
    if attr is not None:
        try:
            ps.attribute(attr)  # an unknown name fails here, before the build
        except ParameterError as exc:
            raise ParameterError(f"--color-by: {exc}") from None
    load_s = time.perf_counter() - t0
    t1 = time.perf_counter()
    tree = ParticleBIH.build(ps)
    build_ms = (time.perf_counter() - t1) * 1e3
    cam = Camera.orbit(ps, azimuth, elevation, projection=projection, zoom=zoom)  # type: ignore[arg-type]
    img = render_particles(tree, cam, width, height, kappa=kappa, opacity=opacity, color_by=attr, cmap=cmap,
                           color_range=vrange, background=bg)
    img.save(output)
    r = float(ps.radii[0])
    how = "given" if radius is not None else (
        f"median distance to the {_ordinal(RADIUS_NEIGHBOURS)}-nearest neighbour" if estimated else "from the file")
    rtext = f"radius {r:.4g} ({how})" if ps.radii.min() == ps.radii.max() else \
        f"radii {ps.radii.min():.4g}..{ps.radii.max():.4g} (from the file)"
    if attr is None:
        ctext = "file colours" if ps.has_colors else "white"
    else:
        lo, hi = img.stats["color_range"]
        ctext = (f"colour by {attr}" + (f" ({DENSITY_NEIGHBOURS} neighbours)" if attr == "log_density"
                                        and attr not in ps.attributes else "")
                 + f" through {cmap} over [{lo:.4g}, {hi:.4g}]")
    out.print(
        f"wrote {output} ({width}x{height}, {file.name}: {len(ps)} particles, {rtext}, {ctext}, "
        f"opacity {opacity:g}, kappa {kappa:g}; load {load_s:.1f} s, BIH build {build_ms:.0f} ms "
        f"({tree.packed.n_nodes} nodes), render {img.stats['ms']:.0f} ms)"
    )


def _ordinal(n: int) -> str:
    return f"{n}{'th' if 10 <= n % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"
