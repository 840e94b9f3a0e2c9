"""``sparsecast view``: the interactive viewer in a web browser."""

from __future__ import annotations

from typing import Annotated, Optional

import typer

from .._util.checks import as_int
from ..errors import ParameterError
from .app import (
    CellOpt, DimsOpt, DtypeOpt, FileArg, LazyOpt, LevelOpt, MemoryLimitOpt, NonFiniteOpt, OrientationOpt, PiecesOpt,
    SchedulerOpt, SpacingOpt, TfOpt,
    TfRangeOpt, ThresholdOpt, UpOpt, ViewOpt, app, err, out, warn,
)
from .inputs import load_input, make_tf, orbit_angles, orbit_frame, preset_range, threshold_value

__all__ = ["view"]


@app.command()
def view(
    file: FileArg = None,
    tf: TfOpt = "viridis",
    tf_range: TfRangeOpt = None,
    threshold: ThresholdOpt = "auto",
    index: Annotated[Optional[str], typer.Option(help="Initial spatial index (default auto: chosen per frame from the occupancy, rebuild-cheap while a TF point is dragged).")] = None,
    cell: CellOpt = None,
    up: UpOpt = None,
    view: ViewOpt = None,
    host: Annotated[str, typer.Option(help="Address to bind; anything but loopback needs --allow-remote.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port (0 picks a free one).")] = 8765,
    allow_remote: Annotated[bool, typer.Option("--allow-remote", help="Allow a non-loopback --host (no authentication!).")] = False,
    no_browser: Annotated[bool, typer.Option("--no-browser", help="Do not open a web browser.")] = False,
    mode: Annotated[str, typer.Option(help="Initial render mode: dvr, iso or iso+dvr (the page switches).")] = "dvr",
    iso: Annotated[Optional[list[float]], typer.Option(
        help="Initial isovalue in data units (repeat for up to 8; default: the middle of the range).")] = None,
    time_step: Annotated[Optional[int], typer.Option("--time", help=(
        "FILE is a time series (a folder of volume files, a quoted glob or a 4-D .npy): start at this step; "
        "the page has a time slider and the TF spans the range of every step."))] = None,
    dims: DimsOpt = None,
    dtype: DtypeOpt = None,
    spacing: SpacingOpt = None,
    orientation: OrientationOpt = None,
    lazy: LazyOpt = None,
    memory_limit: MemoryLimitOpt = None,
    level: LevelOpt = None,
    nonfinite: NonFiniteOpt = None,
    scheduler: SchedulerOpt = None,
    pieces: PiecesOpt = None,
) -> None:
    """Interactive viewer in the web browser: orbit, zoom, edit the TF, switch indices and
    render modes (isovalue slider), clip, show or hide labels (--tf labels), step through
    a time series (--time)."""
    from ..viewer import require_web_stack

    require_web_stack()
    from ..transfer import LabelTransferFunction
    from ..viewer.messages import MODES, CameraSpec
    from ..viewer.server import ViewerServer, check_host
    from ..viewer.session import ViewerData, spec_from_preset

    remote = check_host(host, allow_remote)
    as_int(port, "--port", 0, 65535, expected="0..65535 (0 picks a free port)")
    if mode not in MODES:
        raise ParameterError(f"--mode: expected one of {', '.join(MODES)}, got {mode!r}")
    if iso and mode == "dvr":
        raise ParameterError("--iso: isovalues apply with --mode iso or iso+dvr; got --mode dvr")
    if pieces is not None and scheduler is None:
        raise ParameterError(f"--pieces {pieces}: applies only with --scheduler (a Dask cluster)")
    client = None
    if scheduler is not None:
        from ..distributed import connect

        client = connect(scheduler)
    series = None
    if time_step is not None:
        if file is None:
            raise ParameterError("--time: give the series as FILE (a folder, a quoted glob or a 4-D .npy)")
        from .series import open_series

        series = open_series(file, dict(dims=dims, dtype=dtype, spacing=spacing, orientation=orientation,
                                        nonfinite=nonfinite))
        vol = series[series.step(time_step)]
    else:
        vol = load_input(file, dims, dtype, spacing, orientation=orientation, lazy=lazy, memory_limit=memory_limit,
                         level=level, nonfinite=nonfinite)
    frame = orbit_frame(vol, file, up, view)
    # A series: one TF over the range of every step unless --tf-range fixes it.
    default_range = series.value_range if series is not None and not tf_range else None
    if not tf.lower().endswith(".json") and not tf.lower().startswith("labels"):
        # a preset: resolve --threshold once (auto reads the histogram), for the TF and its editable form
        threshold = threshold_value(threshold, vol, preset_range(vol, tf_range, default_range))
    tfn = make_tf(tf, vol, tf_range, threshold, default_range=default_range)
    az, el = orbit_angles(frame, None, None)
    extra = {} if not iso else {"iso": tuple(iso)}
    data = ViewerData.create(vol if series is None else series, tfn, index=index, cell=cell,
                             time=time_step or 0, camera=CameraSpec(az, el), mode=mode, **extra, **frame)
    if not tf.lower().endswith(".json") and not isinstance(tfn, LabelTransferFunction):
        # Editable form of a preset: its colour map plus a few opacity points.
        data.tf = spec_from_preset(tf, tfn.value_range, threshold)
    data.client, data.pieces = client, pieces
    server = ViewerServer(data, host, port, allow_remote=allow_remote)
    with err.status("preparing the index and kernels"):
        data.warm_up()
    if remote:
        warn(f"serving on {host}, reachable from other machines; the viewer has no authentication")
    what = f"{vol.name} {'x'.join(map(str, vol.dims))}"
    if series is not None:
        what = f"{series.name}: {len(series)} steps of {'x'.join(map(str, vol.dims))}"
    elif data.labels is not None:
        what += f", {len(data.labels.ids)} label ids"
    out.print(f"sparsecast viewer: {server.url}  ({what}; Ctrl-C stops)")
    if not no_browser:
        import threading
        import webbrowser

        opener = threading.Timer(0.5, webbrowser.open, args=(server.url,))
        opener.daemon = True
        opener.start()
    server.serve_forever()
