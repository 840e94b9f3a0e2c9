"""``sparsecast compile``: compile every kernel once, into the on-disk cache."""

from __future__ import annotations

import os
from typing import Annotated, Optional

import typer
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from .._util.checks import as_int
from .app import app, err, out

__all__ = ["compile_command"]


@app.command("compile")
def compile_command(
    only: Annotated[Optional[list[str]], typer.Option(
        "--only", help="Kernel group: volume, surface or particles (repeatable; default all).")] = None,
    dtype: Annotated[Optional[list[str]], typer.Option(
        "--dtype", help="Volume dtype (repeatable, or 'all'); default uint8, uint16, float32.")] = None,
    index: Annotated[Optional[list[str]], typer.Option(
        "--index", help="Volume index NAME[:KEY=VALUE,...] (repeatable); default every index and BIH mode.")] = None,
    list_steps: Annotated[bool, typer.Option("--list", help="Print the steps and exit, compiling nothing.")] = False,
    jobs: Annotated[Optional[str], typer.Option(  # str: a bad value is our one-line error, not click's box
        "--jobs", "-j", help="Processes compiling at once (default: one per core; 1: this one).")] = None,
) -> None:
    """Compile the kernels for the common dtypes ahead of use (cached on disk; a second run takes seconds)."""
    from .. import kernel_cache
    from ..warmup import compile_kernels, plan

    kernel_cache.announce_first_compile(None)  # compiling is what this command is for: its bar says so

    names = ("--dtype", "--index", "--only")
    steps = plan(dtype, index, only, names=names)  # bad values: one error before any work
    jobs = _cores() if jobs is None else as_int(jobs, "--jobs", lo=1)
    if list_steps:
        for step in steps:
            out.print(f"{step.group:<10} {step.label}")
        out.print(f"{len(steps)} steps; cache {kernel_cache.cache_dir() or 'Numba default (__pycache__)'}")
        return
    columns = (TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())
    with Progress(*columns, console=err, transient=False) as bar:
        task = bar.add_task("compiling", total=len(steps))

        def progress(done: int, total: int, label: str) -> None:
            bar.update(task, completed=done, description=label or "done")

        report = compile_kernels(dtype, index, only, progress=progress, names=names, jobs=jobs)
    slowest = max(report.steps, key=lambda s: s[1], default=None)
    out.print(
        f"compiled {len(report.steps)} kernel groups in {report.wall_ms / 1e3:.1f} s "
        f"(Numba compiling {report.compile_ms / 1e3:.1f} s"
        + (f" in {report.jobs} processes" if report.jobs > 1 else "")
        + (f"; slowest: {slowest[0]}, {slowest[1] / 1e3:.1f} s" if slowest else "")
        + f"); cache {report.cache_dir or 'Numba default (__pycache__ beside the sources)'}"
    )


def _cores() -> int:
    """Cores this process may run on (its affinity where the OS tells it)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)
