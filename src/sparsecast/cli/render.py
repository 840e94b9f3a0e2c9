"""``sparsecast render``: one volume to one image."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from .._util.atomic import check_output
from ..errors import ParameterError
from ..image import IMAGE_SUFFIXES
from ..kernel_cache import compile_note, compile_seconds
from .app import (
    AllowOutsideOpt, CellOpt, DimsOpt, DtypeOpt, FileArg, LazyOpt, LevelOpt, MemoryLimitOpt, NonFiniteOpt, OrientationOpt,
    OutputOpt, PiecesOpt, ProjectionOpt, SchedulerOpt, SizeOpt, SpacingOpt, TfOpt, TfRangeOpt, ThresholdOpt, UpOpt,
    ViewOpt, ZoomOpt, app, out, warn,
)
from ..index.registry import check_index_options
from .inputs import load_input, make_tf, orbit_angles, orbit_frame, smoothed_labels
from .parse import parse_background, parse_clip_box, parse_clip_plane, parse_index_spec, parse_size

__all__ = ["render"]

# A named view is its own default angle (0, 0); otherwise the classic three-quarter view.
OrbitAzimuthOpt = Annotated[Optional[float], typer.Option(
    help="Orbit azimuth in degrees about the up axis (default 30; 0 from a --view, which it turns away from).")]
OrbitElevationOpt = Annotated[Optional[float], typer.Option(
    help="Orbit elevation in degrees (default 20; 0 from a --view).")]


@app.command()
def render(
    file: FileArg = None,
    tf: TfOpt = "viridis",
    tf_range: TfRangeOpt = None,
    threshold: ThresholdOpt = "auto",
    azimuth: OrbitAzimuthOpt = None,
    elevation: OrbitElevationOpt = None,
    up: UpOpt = None,
    view: ViewOpt = None,
    projection: ProjectionOpt = "perspective",
    zoom: ZoomOpt = 1.0,
    size: SizeOpt = "512x512",
    dt: Annotated[Optional[float], typer.Option(help="Sample spacing in world units (default: half a voxel).")] = None,
    index: Annotated[str, typer.Option(help="Spatial index (see `sparsecast info --indices`), optionally with build options as NAME:KEY=VALUE[,KEY=VALUE], e.g. bih:mode=single-sample or grid-pc:cell=8; auto picks one from the volume's occupancy under the TF.")] = "auto",
    cell: CellOpt = None,
    shade: Annotated[Optional[bool], typer.Option(
        "--shade/--no-shade", help="Gradient (Blinn-Phong) shading (default: on for the iso modes, off for dvr).")] = None,
    background: Annotated[str, typer.Option(help="black, white, gray, transparent or 'r,g,b[,a]'.")] = "black",
    ert: Annotated[float, typer.Option(help="Early-ray-termination opacity (1 disables).")] = 0.99,
    mode: Annotated[str, typer.Option(help="dvr (volume rendering), iso (isosurfaces of --iso) or iso+dvr (both, "
                                                "in depth order).")] = "dvr",
    iso: Annotated[Optional[list[float]], typer.Option(
        help="Isovalue in data units for --mode iso / iso+dvr (repeat for up to 8 surfaces; "
             "coloured by the TF at the value).")] = None,
    clip_box: Annotated[Optional[str], typer.Option(
        help="Keep only x0,y0,z0,x1,y1,z1 (world units, see `sparsecast info` for the bounds).")] = None,
    clip_plane: Annotated[Optional[list[str]], typer.Option(
        help="Keep the side of the plane px,py,pz,nx,ny,nz that the normal points to (world units; "
             "repeat for up to 6 planes).")] = None,
    clip_cap: Annotated[bool, typer.Option(
        "--clip-cap", help="Shade the cut faces of --clip-box / --clip-plane with their normals (capping; "
                           "--mode dvr).")] = False,
    smooth_labels: Annotated[bool, typer.Option(
        "--smooth-labels", help="With a label TF (--tf labels[:IDS] or a labels .json): smooth boundaries "
                                "from interpolated per-label masks instead of nearest voxels.")] = False,
    time_step: Annotated[Optional[int], typer.Option("--time", help=(
        "Render this step of a time series: FILE is then a folder of volume files (natural order), a quoted "
        "glob pattern or a 4-D .npy."))] = None,
    all_times: Annotated[bool, typer.Option("--all-times", help=(
        "Render every step of the series FILE; -o (and --array) take a %d pattern, e.g. -o frames/%04d.png."
    ))] = False,
    output: OutputOpt = Path("sparsecast.png"),
    array: Annotated[Optional[Path], typer.Option("--array", help="Also save the float32 premultiplied RGBA as .npy.")] = None,
    dims: DimsOpt = None,
    dtype: DtypeOpt = None,
    spacing: SpacingOpt = None,
    orientation: OrientationOpt = None,
    lazy: LazyOpt = None,
    memory_limit: MemoryLimitOpt = None,
    level: LevelOpt = None,
    nonfinite: NonFiniteOpt = None,
    allow_outside_data: AllowOutsideOpt = False,
    scheduler: SchedulerOpt = None,
    pieces: PiecesOpt = None,
) -> None:
    """Render a volume (default: the built-in sparse demo) to an image."""
    from ..camera import Camera
    from ..render import render as do_render

    width, height = parse_size(size)
    series_mode = time_step is not None or all_times
    if series_mode and file is None:
        raise ParameterError("--time/--all-times: give the series as FILE (a folder, a quoted glob or a 4-D .npy)")
    if time_step is not None and all_times:
        raise ParameterError(f"--time {time_step} and --all-times: pick one step or all of them")
    # Every output is checked before any work: a bad --array must neither cost a render
    # nor replace -o's file before it is rejected.
    if not all_times:
        check_output(output, "-o", IMAGE_SUFFIXES)
        if array is not None:
            check_output(array, "--array", {".npy"})
    # Index options are checked before any work: a typo costs no volume load.
    index_name, index_options = parse_index_spec(index)
    if "mode" in index_options:
        # --index bih:mode=... is the BIH's build mode, which render(mode=...) passes on.
        if mode != "dvr":
            raise ParameterError(f"--index {index}: the BIH's mode={index_options['mode']} is a DVR build mode; "
                                 f"--mode {mode} builds its own (exact) index: drop one of them")
        mode = str(index_options.pop("mode"))
    box = parse_clip_box(clip_box)
    planes = [parse_clip_plane(p) for p in clip_plane] if clip_plane else None
    if cell is not None:
        index_options["cell"] = cell
        check_index_options(index_name, index_options)
    if pieces is not None and scheduler is None:
        raise ParameterError(f"--pieces {pieces}: applies only with --scheduler (a Dask cluster)")
    cluster = {}
    if scheduler is not None:
        from ..distributed import connect

        cluster = dict(client=connect(scheduler), pieces=pieces)  # before any work: an unreachable one says so
    t0 = time.perf_counter()
    if series_mode:
        from .series import render_series

        render_series(file, time_step, output, array, tf=tf, tf_range=tf_range, threshold=threshold,
                      size=(width, height), orbit=(azimuth, elevation, up, view, projection, zoom),
                      render_kw=dict(dt=dt, index=index_name, ert=ert, shading=shade,
                                     background=parse_background(background), clip_box=box, clip_planes=planes,
                                     clip_cap=clip_cap, mode=mode, iso=iso or None, **cluster, **index_options),
                      smooth_labels=smooth_labels,
                      load_kw=dict(dims=dims, dtype=dtype, spacing=spacing, orientation=orientation,
                                   nonfinite=nonfinite))
        return
    c0 = compile_seconds()
    vol = load_input(file, dims, dtype, spacing, allow_outside_data, orientation, lazy=lazy,
                     memory_limit=memory_limit, level=level, nonfinite=nonfinite)
    frame = orbit_frame(vol, file, up, view)
    tfn = smoothed_labels(make_tf(tf, vol, tf_range, threshold), tf, smooth_labels)
    if tfn.is_transparent:
        warn(f"transfer function {tf!r} has zero opacity everywhere; the image is background only")
    if iso and mode != "dvr":
        # Documented as a background image (no surface), which looked like a failed render.
        lo, hi = vol.value_range
        outside = [v for v in iso if v < lo or v > hi]
        if outside:
            alone = len(outside) == len(iso) and mode == "iso"
            warn(f"--iso {', '.join(f'{v:g}' for v in outside)}: outside the value range [{lo:g}, {hi:g}] of "
                 f"{vol.name}; " + ("the image is background only" if alone else "no surface for it"))
    az, el = orbit_angles(frame, azimuth, elevation)
    cam = Camera.orbit(vol, az, el, projection=projection, zoom=zoom, **frame)  # type: ignore[arg-type]
    bg = parse_background(background)
    img = do_render(vol, tfn, cam, width, height, dt=dt, index=index_name, ert=ert, shading=shade,
                    background=bg, clip_box=box, clip_planes=planes, clip_cap=clip_cap, mode=mode, iso=iso or None,
                    **cluster, **index_options)
    if cluster:
        cluster["client"].close()
    img.save(output)
    if array is not None:
        img.save(array)
    s = img.stats
    chosen = f"index {s['index']}" + (f" (auto: {s['auto']['reason']})" if "auto" in s else "")
    if "pieces" in s:
        chosen = (f"index {', '.join(s['index'])} on {s['pieces']} pieces, {s['workers']} workers "
                  f"({s['bytes_moved'] / 2**20:.1f} MiB moved)")
    # First-use compilation is timed apart from the build and the frame (both exclude it),
    # and named only when there was some: a start from the kernel cache prints none.
    note = compile_note(compile_seconds() - c0)
    out.print(
        f"wrote {output} ({width}x{height}, {vol.name} {'x'.join(map(str, vol.dims))} {vol.dtype}, "
        + (f"view {frame['view']} ({''.join(vol.orientation)}), " if "view" in frame else "")
        + f"{chosen}, build {s['build_ms']:.0f} ms, {s['ms']:.0f} ms render, {s['samples'] / 1e6:.1f} M samples, "
        f"{s['msamples_per_s']:.1f} M samples/s; " + (f"{note}, " if note else "")
        + f"{time.perf_counter() - t0:.1f} s total)"
    )
