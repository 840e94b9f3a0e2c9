"""``sparsecast render SERIES --time T`` / ``--all-times``: time steps of a series to images.

The camera and TF are fixed for the whole series (the TF spans the range of all
steps unless ``--tf-range`` says otherwise), so frames of an animation are
comparable; each step's index is built from that step's brick statistics.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Optional

from .._util.atomic import check_output
from ..errors import ParameterError
from ..image import IMAGE_SUFFIXES
from .app import err, out, warn
from .inputs import make_tf, nonfinite_policy, orbit_angles, orbit_frame, smoothed_labels
from .parse import parse_dims, parse_spacing

__all__ = ["render_series", "frame_paths", "open_series"]


def open_series(file: Path, load_kw: dict[str, Any]):
    """The series ``file`` names (a folder, a glob or a 4-D .npy) with the raw-file and
    grid options of ``load_kw`` (``dims``, ``dtype``, ``spacing``, ``orientation``) and its
    NaN/Inf policy (``nonfinite``, for every step)."""
    from ..io import load_series

    kw = {}
    if load_kw.get("dims"):
        kw["dims"] = parse_dims(load_kw["dims"])
    if load_kw.get("dtype"):
        kw["dtype"] = load_kw["dtype"]
    if load_kw.get("orientation"):
        kw["orientation"] = load_kw["orientation"]
    if load_kw.get("nonfinite"):
        kw["nonfinite"] = nonfinite_policy(load_kw["nonfinite"])
    spacing = parse_spacing(load_kw["spacing"]) if load_kw.get("spacing") else None
    return load_series(str(file), spacing=spacing, **kw)


def frame_paths(pattern: Path, n: int, option: str, suffixes) -> list[Path]:
    """``pattern % t`` for every step (``frames/%04d.png``), each checked as an output."""
    text = str(pattern)
    try:
        names = [text % t for t in range(n)]
    except (TypeError, ValueError):
        raise ParameterError(f"{option}: --all-times needs a pattern with one integer field such as "
                             f"frames/%04d.png, got {text!r}") from None
    if n > 1 and names[0] == names[1]:
        raise ParameterError(f"{option}: {text!r} gives every step the same name; expected a pattern such as "
                             "frames/%04d.png")
    return [check_output(Path(p), option, suffixes) for p in names]


def render_series(file: Path, time_step: Optional[int], output: Path, array: Optional[Path], *, tf: str,
                  tf_range: Optional[str], threshold: str, size: tuple[int, int], orbit: tuple,
                  render_kw: dict[str, Any], load_kw: dict[str, Any], smooth_labels: bool = False) -> None:
    """Render one step (``time_step``) or all of them (``time_step`` None) of the series ``file``."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from ..camera import Camera
    from ..render import render as do_render

    series = open_series(file, load_kw)
    steps = [series.step(time_step)] if time_step is not None else list(range(len(series)))
    if time_step is None:
        images = frame_paths(output, len(series), "-o", IMAGE_SUFFIXES)
        arrays = frame_paths(array, len(series), "--array", {".npy"}) if array is not None else None
    else:
        images, arrays = {steps[0]: output}, ({steps[0]: array} if array is not None else None)
    t0 = time.perf_counter()
    first = series[steps[0]]
    azimuth, elevation, up, view, projection, zoom = orbit
    frame = orbit_frame(first, file, up, view)
    # One TF for every step: over the range of all of them unless --tf-range fixes it.
    tfn = smoothed_labels(make_tf(tf, first, tf_range, threshold,
                                  default_range=None if tf_range else series.value_range), tf, smooth_labels)
    if tfn.is_transparent:
        warn(f"transfer function {tf!r} has zero opacity everywhere; the images are background only")
    az, el = orbit_angles(frame, azimuth, elevation)
    cam = Camera.orbit(first, az, el, projection=projection, zoom=zoom, **frame)  # type: ignore[arg-type]
    width, height = size
    render_ms = 0.0
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, console=err, transient=True, disable=len(steps) == 1) as progress:
        task = progress.add_task(f"rendering {series.name}", total=len(steps))
        for t in steps:
            vol = series[t]
            img = do_render(vol, tfn, cam, width, height, **render_kw)
            img.save(images[t])
            if arrays is not None:
                img.save(arrays[t])
            render_ms += img.stats["ms"]
            progress.advance(task)
    what = (f"{len(steps)} frames {images[steps[0]]} .. {images[steps[-1]]}" if len(steps) > 1
            else f"{images[steps[0]]} (step {steps[0]}: {series.names[steps[0]]})")
    out.print(
        f"wrote {what} ({width}x{height}, {series.name}: {len(series)} steps of "
        f"{'x'.join(map(str, first.dims))} {first.dtype}, TF over [{tfn.value_range[0]:g}, {tfn.value_range[1]:g}], "
        f"{render_ms / len(steps):.0f} ms render per frame; {time.perf_counter() - t0:.1f} s total)"
    )
