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
    index: Annotated[str, typer.Option(help="Spatial index (see `sparsecast info --indices`), optionally with build options as NAME:KEY=VALUE[,KEY=VALUE], e.g. bih:mode=single-sample or grid-pc:cell=8.")] = "naive",
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
    from .render import render as do_render

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
    from .bench.harness import parse_method

    index_name, index_options = parse_method(index)
    if cell is not None:
        index_options["cell"] = cell
    img = do_render(vol, tfn, cam, width, height, dt=dt, index=index_name, ert=ert, shading=shade,
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
    suite: Annotated[Optional[str], typer.Option(help="quick (the default run), paper (the papers' evaluation, ~30 min), sweep (Fig. 5 clusters), bih or surface; resumable, with a Markdown report and figures.")] = None,
    dataset: Annotated[Optional[list[str]], typer.Option("--dataset", "-d", help="Dataset name (repeatable); default: the suite's.")] = None,
    method: Annotated[Optional[list[str]], typer.Option("--method", "-m", help="Index name, optionally with options as name:key=value (repeatable); default all.")] = None,
    dense: Annotated[Optional[bool], typer.Option("--dense/--no-dense", help="Also bench a TF with no empty space (default: yes).")] = None,
    size: Annotated[Optional[list[str]], typer.Option(help="Image size WIDTHxHEIGHT (repeatable); default 512x512, paper 512 and 1024.")] = None,
    views: Annotated[Optional[int], typer.Option(help="Orbit views per axis (x, y, z); default: the suite's two fixed views, paper 4.")] = None,
    repeat: Annotated[Optional[int], typer.Option(help="Timed runs per measurement, median reported (quick 3, paper 1: views are samples too).")] = None,
    warmup: Annotated[Optional[int], typer.Option(help="Untimed runs before timing (quick 1, paper 0).")] = None,
    dt: Annotated[Optional[float], typer.Option(help="Sample spacing (default half a voxel).")] = None,
    peer: Annotated[Optional[list[str]], typer.Option("--peer", help="Peer renderer run on the same cases: vtk, yt (repeatable; 'none' for none).")] = None,
    peer_views: Annotated[Optional[int], typer.Option(help="Views the peers render (the first N; default 2, paper 1).")] = None,
    dense_views: Annotated[Optional[int], typer.Option(help="Views rendered with the dense TF (the first N; quick 1, paper 2).")] = None,
    section: Annotated[Optional[list[str]], typer.Option("--section", help="Extra section module: bih, surface (repeatable; 'none' for none).")] = None,
    json_path: Annotated[Optional[Path], typer.Option("--json", help="Records file (default bench-results/bench-<time>.json, or bench-results/<suite>/records.json); a .jsonl journal beside it makes reruns resume.")] = None,
    report: Annotated[Optional[Path], typer.Option("--report", help="Write the Markdown report here (default with --suite: BENCHMARKS.md beside the records).")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Also write matplotlib figures (PNG) into this folder.")] = None,
    images: Annotated[Optional[Path], typer.Option("--images", help="Save our and the peers' images (PNG) into this folder.")] = None,
    fresh: Annotated[bool, typer.Option("--fresh", help="Discard the journal of an earlier run instead of resuming it.")] = False,
    compare: Annotated[Optional[tuple[Path, Path]], typer.Option("--compare", help="OLD.json NEW.json: print per-case time ratios (new / old) and exit.")] = None,
) -> None:
    """Time every index on the demo and the shared real volumes; print a table, write JSON.

    With --suite, also a Markdown report and figures; an interrupted run resumes
    where it stopped when the same command is run again.
    """
    if compare is not None:
        _bench_compare(*compare)
        return
    from .bench import format_table, run_benchmarks, write_json
    from .bench.report import format_summary
    from .bench.harness import BenchConfig, finished_records, parse_method
    from .bench.progress import Progress, ResultStore
    from .bench.suites import get_suite, orbit_views

    plan = get_suite(suite or "quick")
    sizes = [_parse_size(s) for s in size] if size else None
    if (repeat is not None and repeat < 1) or (warmup is not None and warmup < 0):
        raise ParameterError(f"--repeat must be >= 1 and --warmup >= 0, got {repeat}, {warmup}")
    if views is not None and views < 1:
        raise ParameterError(f"--views: expected at least 1 view per axis, got {views}")
    cfg = BenchConfig.from_suite(
        plan, datasets=dataset, methods=method, sizes=sizes, repeat=repeat, warmup=warmup, dt=dt,
        dense_tf=dense, views=orbit_views(views) if views else None, peer_views=peer_views, dense_views=dense_views,
        peers=_none_list(peer), sections=_none_list(section),
    )
    _check_bench_names(cfg)
    for m in cfg.methods:
        parse_method(m)  # validates names and options up front
    # A suite's report, figures and images go beside its records (default bench-results/<suite>/).
    out_dir = None
    if suite:
        out_dir = json_path.parent if json_path is not None else Path("bench-results") / plan.name
    if json_path is None:
        json_path = out_dir / "records.json" if out_dir else Path("bench-results") / f"bench-{time.strftime('%Y%m%d-%H%M%S')}.json"
    if out_dir is not None:
        report = report or out_dir / "BENCHMARKS.md"
        plot = plot or out_dir / "figures"
        images = images or out_dir / "images"
    cfg.images_dir = images
    store = ResultStore(json_path.with_suffix(".jsonl"), fresh=fresh)
    if store.resumed:
        _err.print(f"resuming: {store.resumed} records from {json_path.with_suffix('.jsonl')}")
    progress = Progress(0, console=_err, label=f"sparsecast bench --suite {plan.name}")
    interrupted = False
    try:
        records = run_benchmarks(cfg, progress=progress, store=store)
    except KeyboardInterrupt:
        # Ctrl-C: the outputs below show the finished cases; the journal resumes the rest.
        interrupted = True
        records = finished_records(store)
    finally:
        progress.close()
    # A table this wide is unreadable folded at 80 columns when piped to a file.
    wide = _out if _out.is_terminal else Console(soft_wrap=True, width=200)
    # A suite run has hundreds of records: its console shows the headline, the report the rest.
    wide.print(format_summary(records) if suite else format_table(records))
    write_json(records, json_path)
    _out.print(f"wrote {len(records)} records to {json_path}")
    figures = []
    if plot is not None:
        from .bench.plots import write_plots

        figures = write_plots(records, plot)
        for fig_path in figures:
            _out.print(f"wrote {fig_path}")
    if report is not None:
        from .bench.markdown import markdown_report, write_markdown

        command = "sparsecast " + " ".join(sys.argv[1:])
        text = markdown_report(records, suite=plan.name, command=command, figures=figures,
                               relative_to=report.parent)
        _out.print(f"wrote {write_markdown(text, report)}")
    if interrupted:
        _err.print(f"interrupted: {progress.done_count} of {progress.total} cases are kept in "
                   f"{store.path}; run the same command again to resume")
        raise typer.Exit(130)


def _none_list(values: Optional[list[str]]) -> Optional[list[str]]:
    """Repeatable option values, with 'none' meaning an explicit empty list."""
    if values is None:
        return None
    return [] if [v.lower() for v in values] == ["none"] else values


def _check_bench_names(cfg) -> None:
    from .bench import DATASETS
    from .bench.peers import PEERS

    for n in cfg.datasets:
        if n not in DATASETS:
            raise ParameterError(f"--dataset: unknown dataset {n!r}; expected one of {', '.join(DATASETS)}")
    for p in cfg.peers:
        if p not in PEERS:
            raise ParameterError(f"--peer: unknown peer {p!r}; expected one of {', '.join(PEERS)} or none")
    for s in cfg.sections:
        if not s.isidentifier():
            raise ParameterError(f"--section: expected a module name like bih or surface, got {s!r}")


def _bench_compare(old: Path, new: Path) -> None:
    from .bench.compare import compare_records, format_comparison
    from .bench.report import load_records

    cases, only_old, only_new = compare_records(load_records(old), load_records(new))
    if not cases:
        raise ParameterError(f"--compare: {old} and {new} have no case in common; expected two runs of the same suite")
    wide = _out if _out.is_terminal else Console(soft_wrap=True, width=160)
    wide.print(format_comparison(cases, only_old, only_new))


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


from .surface.cli import render_mesh  # noqa: E402  (its heavy imports are deferred)

app.command("render-mesh")(render_mesh)


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
