"""The ``sparsecast`` command line: ``render``, ``info``, ``bench`` and ``view``."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Annotated, Optional

import numpy as np
import typer
from rich.console import Console

from .errors import ParameterError, SparsecastError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Fast ray casting of sparse volumes.",
)
_out = Console(soft_wrap=True)
_err = Console(stderr=True, soft_wrap=True)

FileArg = Annotated[
    Optional[Path],
    typer.Argument(help="Volume file (.nrrd .nhdr .nii .nii.gz .raw .npy .tif); omit for the built-in demo."),
]
TfOpt = Annotated[
    str, typer.Option("--tf", help="Preset name (see `sparsecast info --presets`) or a TF .json file.")
]
# Options shared by the commands that load and classify a volume.
TfRangeOpt = Annotated[Optional[str], typer.Option(help="Data range 'lo,hi' the TF spans (default: the volume's).")]
ThresholdOpt = Annotated[float, typer.Option(help="Colour-map presets: transparent below this fraction of the range.")]
DimsOpt = Annotated[Optional[str], typer.Option(help="Raw files: NXxNYxNZ.")]
DtypeOpt = Annotated[Optional[str], typer.Option(help="Raw files: uint8, uint16, int16, float32, float64.")]
SpacingOpt = Annotated[Optional[str], typer.Option(help="Override voxel spacing 'sx,sy,sz'.")]


def _parse_size(size: str) -> tuple[int, int]:
    parts = size.lower().split("x")
    try:
        if len(parts) == 1:
            w = h = int(parts[0])
        elif len(parts) == 2:
            w, h = int(parts[0]), int(parts[1])
        else:
            raise ValueError
    except ValueError:
        raise ParameterError(f"--size: expected WIDTHxHEIGHT like 512x512, got {size!r}") from None
    return w, h


def _parse_pair(text: str, name: str) -> tuple[float, float]:
    try:
        lo, hi = (float(x) for x in text.split(","))
    except ValueError:
        raise ParameterError(f"{name}: expected two numbers 'lo,hi', got {text!r}") from None
    return lo, hi


def _load(file: Optional[Path], dims: Optional[str], dtype: Optional[str], spacing: Optional[str]):
    from .datasets import demo_volume
    from .io import load_volume

    if file is None:
        return demo_volume()
    kw = {}
    if dims:
        try:
            kw["dims"] = tuple(int(x) for x in dims.lower().split("x"))
        except ValueError:
            raise ParameterError(f"--dims: expected NXxNYxNZ like 256x256x128, got {dims!r}") from None
    if dtype:
        kw["dtype"] = dtype
    if spacing:
        try:
            vals = [float(x) for x in spacing.split(",")]
        except ValueError:
            raise ParameterError(f"--spacing: expected 'sx,sy,sz' or one number, got {spacing!r}") from None
        kw["spacing"] = vals[0] if len(vals) == 1 else vals
    return load_volume(file, **kw)


def _make_tf(spec: str, vol, tf_range: Optional[str], threshold: float):
    from .transfer import TransferFunction

    value_range = _parse_pair(tf_range, "--tf-range") if tf_range else vol.value_range
    if spec.lower().endswith(".json"):
        tf = TransferFunction.load(spec)
        return tf.with_range(value_range) if tf_range else tf
    return TransferFunction.preset(spec, value_range, threshold=threshold)


@app.command()
def render(
    file: FileArg = None,
    tf: TfOpt = "viridis",
    tf_range: TfRangeOpt = None,
    threshold: ThresholdOpt = 0.1,
    azimuth: Annotated[float, typer.Option(help="Orbit azimuth in degrees.")] = 30.0,
    elevation: Annotated[float, typer.Option(help="Orbit elevation in degrees.")] = 20.0,
    projection: Annotated[str, typer.Option(help="perspective or orthographic.")] = "perspective",
    zoom: Annotated[float, typer.Option(help="Magnification (>1 zooms in).")] = 1.0,
    size: Annotated[str, typer.Option(help="Image size WIDTHxHEIGHT.")] = "512x512",
    dt: Annotated[Optional[float], typer.Option(help="Sample spacing in world units (default: half a voxel).")] = None,
    index: Annotated[str, typer.Option(help="Spatial index (see `sparsecast info --indices`).")] = "naive",
    cell: Annotated[Optional[int], typer.Option(help="Grid indices: voxels per macrocell edge (4, 8, 16, 32, 64).")] = None,
    shade: Annotated[bool, typer.Option("--shade/--no-shade", help="Gradient (Blinn-Phong) shading.")] = False,
    background: Annotated[str, typer.Option(help="black, white, gray, transparent or 'r,g,b[,a]'.")] = "black",
    ert: Annotated[float, typer.Option(help="Early-ray-termination opacity (1 disables).")] = 0.99,
    output: Annotated[Path, typer.Option("-o", "--output", help="Image file (.png, .jpg, .tif, or .npy).")] = Path("sparsecast.png"),
    array: Annotated[Optional[Path], typer.Option("--array", help="Also save the float32 premultiplied RGBA as .npy.")] = None,
    dims: DimsOpt = None,
    dtype: DtypeOpt = None,
    spacing: SpacingOpt = None,
) -> None:
    """Render a volume (default: the built-in sparse demo) to an image."""
    from .camera import Camera
    from .renderers import render as do_render

    width, height = _parse_size(size)
    t0 = time.perf_counter()
    vol = _load(file, dims, dtype, spacing)
    tfn = _make_tf(tf, vol, tf_range, threshold)
    if tfn.is_transparent:
        _err.print(f"[yellow]warning:[/] transfer function {tf!r} has zero opacity everywhere; the image is background only")
    cam = Camera.orbit(vol, azimuth, elevation, projection=projection, zoom=zoom)  # type: ignore[arg-type]
    bg: str | list[float] = background
    if "," in background:
        bg = list(_parse_pair_n(background, "--background"))
    index_options = {} if cell is None else {"cell": cell}
    img = do_render(vol, tfn, cam, width, height, dt=dt, index=index, ert=ert, shading=shade,
                    background=bg, **index_options)
    img.save(output)
    if array is not None:
        if array.suffix.lower() != ".npy":
            raise ParameterError(f"--array: expected a .npy file name, got {str(array)!r}")
        img.save(array)
    s = img.stats
    _out.print(
        f"wrote {output} ({width}x{height}, {vol.name} {'x'.join(map(str, vol.dims))} {vol.dtype}, "
        f"index {s['index']}, {s['ms']:.0f} ms render, {s['samples'] / 1e6:.1f} M samples, "
        f"{s['msamples_per_s']:.1f} M samples/s; {time.perf_counter() - t0:.1f} s total)"
    )


def _parse_pair_n(text: str, name: str) -> tuple[float, ...]:
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise ParameterError(f"{name}: expected comma-separated numbers, got {text!r}") from None


def _histogram_sketch(data: np.ndarray, bins: int = 48) -> str:
    """One line of block characters: log-scaled histogram of the voxel values."""
    sample = data.ravel()[:: max(1, data.size // 4_000_000)]  # enough for a sketch
    counts, _ = np.histogram(sample, bins=bins)
    levels = " ▁▂▃▄▅▆▇█"
    logc = np.log1p(counts.astype(np.float64))
    top = logc.max() or 1.0
    return "".join(levels[int(round(v / top * (len(levels) - 1)))] for v in logc)


@app.command()
def info(
    file: FileArg = None,
    tf: TfOpt = "viridis",
    tf_range: TfRangeOpt = None,
    threshold: ThresholdOpt = 0.1,
    brick_size: Annotated[int, typer.Option(help="Brick edge in cells for the occupancy figure.")] = 8,
    dims: DimsOpt = None,
    dtype: DtypeOpt = None,
    spacing: SpacingOpt = None,
    presets: Annotated[bool, typer.Option("--presets", help="List TF presets and exit.")] = False,
    indices: Annotated[bool, typer.Option("--indices", help="List spatial indices and exit.")] = False,
) -> None:
    """Describe a volume: dims, dtype, spacing, value range, histogram, occupancy for a TF."""
    from .index import available_indices
    from .transfer import PRESETS

    if presets:
        _out.print("TF presets: " + ", ".join(PRESETS))
        return
    if indices:
        _out.print("indices: " + ", ".join(available_indices()))
        return
    vol = _load(file, dims, dtype, spacing)
    tfn = _make_tf(tf, vol, tf_range, threshold)
    lo, hi = vol.value_range
    bricks = vol.brick_stats(brick_size)
    t0 = time.perf_counter()
    nonempty = tfn.classify(bricks.vmin, bricks.vmax)
    classify_ms = (time.perf_counter() - t0) * 1e3
    nx, ny, nz = vol.dims
    _out.print(f"[bold]{vol.name}[/]  {file if file else '(built-in demo)'}")
    _out.print(f"  dims      {nx} x {ny} x {nz}  ({vol.nbytes / 2**20:.1f} MiB, dtype {vol.dtype})")
    _out.print(f"  spacing   {tuple(round(float(s), 6) for s in vol.spacing)}   origin {tuple(round(float(o), 6) for o in vol.origin)}")
    _out.print(f"  range     [{lo:g}, {hi:g}]")
    _out.print(f"  histogram |{_histogram_sketch(vol.data)}|  (log counts, {lo:g} .. {hi:g})")
    _out.print(
        f"  occupancy {100 * nonempty.mean():.2f} % of {nonempty.size} bricks of {brick_size}^3 are non-empty "
        f"for TF {tfn.name!r} over [{tfn.value_range[0]:g}, {tfn.value_range[1]:g}] "
        f"(brick stats {bricks.build_ms:.1f} ms, classify {classify_ms:.3f} ms)"
    )


@app.command()
def bench(
    dataset: Annotated[Optional[list[str]], typer.Option("--dataset", "-d", help="Dataset name (repeatable); default: the demo and every shared volume present.")] = None,
    method: Annotated[Optional[list[str]], typer.Option("--method", "-m", help="Index name, optionally with options as name:key=value (repeatable); default all.")] = None,
    dense: Annotated[bool, typer.Option("--dense/--no-dense", help="Also bench a TF with no empty space.")] = True,
    size: Annotated[str, typer.Option(help="Image size WIDTHxHEIGHT.")] = "512x512",
    repeat: Annotated[int, typer.Option(help="Timed runs per measurement (median reported).")] = 5,
    warmup: Annotated[int, typer.Option(help="Untimed runs before timing.")] = 1,
    dt: Annotated[Optional[float], typer.Option(help="Sample spacing (default half a voxel).")] = None,
    json_path: Annotated[Optional[Path], typer.Option("--json", help="Where to write the records (default bench-results/bench-<time>.json).")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Also write matplotlib figures (PNG) into this folder.")] = None,
) -> None:
    """Time every index on the demo and the shared real volumes; print a table, write JSON."""
    from .bench import DATASETS, BenchConfig, format_table, run_benchmarks, write_json
    from .bench.harness import parse_method

    width, height = _parse_size(size)
    if repeat < 1 or warmup < 0:
        raise ParameterError(f"--repeat must be >= 1 and --warmup >= 0, got {repeat}, {warmup}")
    names = dataset or [n for n, d in DATASETS.items() if d.default]
    for n in names:
        if n not in DATASETS:
            raise ParameterError(f"--dataset: unknown dataset {n!r}; expected one of {', '.join(DATASETS)}")
    methods = method or _default_bench_methods()
    for m in methods:
        parse_method(m)  # validates names and options up front
    cfg = BenchConfig(datasets=names, methods=methods, width=width, height=height,
                      repeat=repeat, warmup=warmup, dt=dt, dense_tf=dense)
    with _err.status("benchmarking") as status:
        records = run_benchmarks(cfg, progress=lambda msg: status.update(f"benchmarking: {msg}"))
    # A table this wide is unreadable folded at 80 columns when piped to a file.
    wide = _out if _out.is_terminal else Console(soft_wrap=True, width=200)
    wide.print(format_table(records))
    path = json_path or Path("bench-results") / f"bench-{time.strftime('%Y%m%d-%H%M%S')}.json"
    write_json(records, path)
    _out.print(f"wrote {len(records)} records to {path}")
    if plot is not None:
        from .bench.plots import write_plots

        for fig_path in write_plots(records, plot):
            _out.print(f"wrote {fig_path}")


@app.command()
def view(
    file: FileArg = None,
    tf: TfOpt = "viridis",
    tf_range: TfRangeOpt = None,
    threshold: ThresholdOpt = 0.1,
    index: Annotated[Optional[str], typer.Option(help="Initial spatial index (default grid-pc).")] = None,
    cell: Annotated[Optional[int], typer.Option(help="Grid indices: voxels per macrocell edge (4, 8, 16, 32, 64).")] = None,
    host: Annotated[str, typer.Option(help="Address to bind; anything but loopback needs --allow-remote.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port (0 picks a free one).")] = 8765,
    allow_remote: Annotated[bool, typer.Option("--allow-remote", help="Allow a non-loopback --host (no authentication!).")] = False,
    no_browser: Annotated[bool, typer.Option("--no-browser", help="Do not open a web browser.")] = False,
    dims: DimsOpt = None,
    dtype: DtypeOpt = None,
    spacing: SpacingOpt = None,
) -> None:
    """Interactive viewer in the web browser: orbit, zoom, edit the TF, switch indices."""
    from .viewer import require_web_stack

    require_web_stack()
    from .viewer.server import ViewerServer, check_host
    from .viewer.session import ViewerData, spec_from_preset

    remote = check_host(host, allow_remote)
    if not 0 <= port <= 65535:
        raise ParameterError(f"--port: expected 0..65535 (0 picks a free port), got {port}")
    vol = _load(file, dims, dtype, spacing)
    tfn = _make_tf(tf, vol, tf_range, threshold)
    data = ViewerData.create(vol, tfn, index=index, cell=cell)
    if not tf.lower().endswith(".json"):
        # Editable form of a preset: its colour map plus a few opacity points.
        data.tf = spec_from_preset(tf, tfn.value_range, threshold)
    server = ViewerServer(data, host, port, allow_remote=allow_remote)
    with _err.status("preparing the index and kernels"):
        data.warm_up()
    if remote:
        _err.print(f"[yellow]warning:[/] serving on {host}, reachable from other machines; the viewer has no authentication")
    _out.print(f"sparsecast viewer: {server.url}  ({vol.name} {'x'.join(map(str, vol.dims))}; Ctrl-C stops)")
    if not no_browser:
        import threading
        import webbrowser

        opener = threading.Timer(0.5, webbrowser.open, args=(server.url,))
        opener.daemon = True
        opener.start()
    server.serve_forever()


def _default_bench_methods() -> list[str]:
    from .index import available_indices

    return available_indices()


def main() -> None:
    """Console entry point: bad input becomes one line on stderr and exit status 2."""
    try:
        app()
    except SparsecastError as exc:
        _err.print(f"[red]error:[/] {exc}", highlight=False, soft_wrap=True)
        sys.exit(2)
    except (FileNotFoundError, PermissionError, IsADirectoryError) as exc:
        _err.print(f"[red]error:[/] {exc}", highlight=False, soft_wrap=True)
        sys.exit(2)
    except KeyboardInterrupt:
        _err.print("interrupted")
        sys.exit(130)


if __name__ == "__main__":
    main()
