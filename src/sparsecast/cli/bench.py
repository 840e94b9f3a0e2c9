"""``sparsecast bench``: run a benchmark suite (resumable), print and write its results;
``--compare`` two runs."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from .._util.checks import as_int, fail, positive_float
from ..bench.suites import suites_help
from ..errors import ParameterError
from .app import app, err, out, plain_console
from .parse import none_list, parse_index_spec, parse_size

__all__ = ["bench"]


@app.command()
def bench(
    suite: Annotated[Optional[str], typer.Option(help=f"{suites_help()}; resumable, with a Markdown report and figures (durations: 2-core machines; paper, features and surface with the interleaved rounds).")] = None,
    dataset: Annotated[Optional[list[str]], typer.Option("--dataset", "-d", help="Dataset name (repeatable); default: the suite's. --suite surface also takes its meshes (bunny, dragon, dragons-7m, ...); with --suite features a volume is measured by the features section alone.")] = None,
    method: Annotated[Optional[list[str]], typer.Option("--method", "-m", help="Index name, optionally with options as name:key=value (repeatable); default all.")] = None,
    dense: Annotated[Optional[bool], typer.Option("--dense/--no-dense", help="Also bench a TF with no empty space (default: yes).")] = None,
    size: Annotated[Optional[list[str]], typer.Option(help="Image size WIDTHxHEIGHT (repeatable); default 512x512, paper 512 and 1024.")] = None,
    views: Annotated[Optional[int], typer.Option(help="Orbit views per axis (x, y, z); default: the suite's two fixed views, paper 4.")] = None,
    repeat: Annotated[Optional[int], typer.Option(help="Timed runs per measurement, median reported; frames in interleaved rounds (every suite 3).")] = None,
    warmup: Annotated[Optional[int], typer.Option(help="Untimed runs before timing (every suite 1; frames take at least 1).")] = None,
    dt: Annotated[Optional[float], typer.Option(help="Sample spacing (default half a voxel).")] = None,
    peer: Annotated[Optional[list[str]], typer.Option("--peer", help="Peer renderer run on the same cases: vtk, yt, pyvista (repeatable; 'none' for none).")] = None,
    peer_views: Annotated[Optional[int], typer.Option(help="Views the peers render (the first N; default 2, paper 1).")] = None,
    dense_views: Annotated[Optional[int], typer.Option(help="Views rendered with the dense TF (the first N; quick 1, paper 2).")] = None,
    section: Annotated[Optional[list[str]], typer.Option("--section", help="Extra section module: bih, surface (repeatable; 'none' for none).")] = None,
    json_path: Annotated[Optional[Path], typer.Option("--json", help="Records file (default: bench-<time>.json in bench-results/, with --suite records.json in bench-results/<suite>/); a .jsonl journal beside it makes reruns resume.")] = None,
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
        _compare(*compare)
        return
    from ..bench import format_table, run_benchmarks, write_json
    from ..bench.config import BenchConfig
    from ..bench.harness import finished_records
    from ..bench.progress import Progress, ResultStore
    from ..bench.report import format_features, format_scale, format_summary, format_surface
    from ..bench.suites import get_suite, orbit_views

    plan = get_suite(suite or "quick")
    sizes = [parse_size(s) for s in size] if size else None
    if repeat is not None:
        as_int(repeat, "--repeat", lo=1)
    if warmup is not None:
        as_int(warmup, "--warmup", lo=0)
    if views is not None:
        as_int(views, "--views", lo=1, expected="at least 1 view per axis")
    if dt is not None:  # (else the first case to render would say so, after loading its volume)
        positive_float(dt, "--dt", expected="a positive world-space step")
    for value, option in ((peer_views, "--peer-views"), (dense_views, "--dense-views")):
        if value is not None:  # (a negative count would slice views off the end)
            as_int(value, option, lo=0)
    cfg = BenchConfig.from_suite(
        plan, datasets=dataset, methods=method, sizes=sizes, repeat=repeat, warmup=warmup, dt=dt,
        dense_tf=dense, views=orbit_views(views) if views else None, peer_views=peer_views, dense_views=dense_views,
        peers=none_list(peer), sections=none_list(section),
    )
    _check_names(cfg)
    for m in cfg.methods:
        parse_index_spec(m)  # validates names and options up front
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
        err.print(f"resuming: {store.resumed} records from {json_path.with_suffix('.jsonl')}")
    progress = Progress(0, console=err, label=f"sparsecast bench --suite {plan.name}")
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
    wide = out if out.is_terminal else plain_console(200)
    # A suite run has hundreds of records: its console shows the headline, the report the rest.
    headline = format_summary(records) if suite else format_table(records)
    if headline.row_count or not suite:  # a sections-only suite (surface) has no volume rows
        wide.print(headline)
    for section_table in (format_features(records), format_surface(records), format_scale(records)):
        if section_table is not None:
            wide.print(section_table)
    write_json(records, json_path)
    out.print(f"wrote {len(records)} records to {json_path}")
    figures = []
    if plot is not None:
        from ..bench.plots import write_plots

        figures = write_plots(records, plot)
        for fig_path in figures:
            out.print(f"wrote {fig_path}")
    if report is not None:
        from ..bench.markdown import markdown_report, write_markdown

        command = "sparsecast " + " ".join(sys.argv[1:])
        text = markdown_report(records, suite=plan.name, command=command, figures=figures,
                               relative_to=report.parent)
        out.print(f"wrote {write_markdown(text, report)}")
    if interrupted:
        err.print(f"interrupted: {progress.done_count} of {progress.total} cases are kept in "
                  f"{store.path}; run the same command again to resume")
        raise typer.Exit(130)


def _check_names(cfg) -> None:
    """Unknown datasets, peers and section names fail before anything is measured."""
    from ..bench import DATASETS
    from ..bench.config import section_dataset_names
    from ..bench.peers import PEERS

    for n in cfg.route_datasets():
        extra = [m for s in cfg.sections for m in section_dataset_names(s)]
        names = dict.fromkeys([*DATASETS, *extra])  # a section may take the volumes too (features)
        raise ParameterError(f"--dataset: unknown dataset {n!r}; expected one of {', '.join(names)}")
    for p in cfg.peers:
        if p not in PEERS:
            raise ParameterError(f"--peer: unknown peer {p!r}; expected one of {', '.join(PEERS)} or none")
    for s in cfg.sections:
        if not s.isidentifier():
            raise fail("--section", "a module name like bih or surface", s)


def _compare(old: Path, new: Path) -> None:
    """``--compare OLD NEW``: per-case time ratios of two record files."""
    from ..bench.compare import compare_records, format_comparison
    from ..bench.report import load_records

    cases, only_old, only_new = compare_records(load_records(old), load_records(new))
    if not cases:
        raise ParameterError(f"--compare: {old} and {new} have no case in common; expected two runs of the same suite")
    wide = out if out.is_terminal else plain_console(160)
    wide.print(format_comparison(cases, only_old, only_new))
