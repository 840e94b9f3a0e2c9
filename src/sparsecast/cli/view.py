"""``sparsecast view``: the interactive viewer in a web browser."""

from __future__ import annotations

from typing import Annotated, Optional

import typer

from .._util.checks import as_int
from .app import (
    CellOpt, DimsOpt, DtypeOpt, FileArg, OrientationOpt, SpacingOpt, TfOpt, TfRangeOpt, ThresholdOpt, UpOpt, ViewOpt,
    app, err, out, warn,
)
from .inputs import load_input, make_tf, orbit_angles, orbit_frame

__all__ = ["view"]


@app.command()
def view(
    file: FileArg = None,
    tf: TfOpt = "viridis",
    tf_range: TfRangeOpt = None,
    threshold: ThresholdOpt = 0.1,
    index: Annotated[Optional[str], typer.Option(help="Initial spatial index (default auto: chosen per frame from the occupancy, rebuild-cheap while a TF point is dragged).")] = None,
    cell: CellOpt = None,
    up: UpOpt = None,
    view: ViewOpt = None,
    host: Annotated[str, typer.Option(help="Address to bind; anything but loopback needs --allow-remote.")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="TCP port (0 picks a free one).")] = 8765,
    allow_remote: Annotated[bool, typer.Option("--allow-remote", help="Allow a non-loopback --host (no authentication!).")] = False,
    no_browser: Annotated[bool, typer.Option("--no-browser", help="Do not open a web browser.")] = False,
    dims: DimsOpt = None,
    dtype: DtypeOpt = None,
    spacing: SpacingOpt = None,
    orientation: OrientationOpt = None,
) -> None:
    """Interactive viewer in the web browser: orbit, zoom, edit the TF, switch indices."""
    from ..viewer import require_web_stack

    require_web_stack()
    from ..viewer.server import ViewerServer, check_host
    from ..viewer.messages import CameraSpec
    from ..viewer.session import ViewerData, spec_from_preset

    remote = check_host(host, allow_remote)
    as_int(port, "--port", 0, 65535, expected="0..65535 (0 picks a free port)")
    vol = load_input(file, dims, dtype, spacing, orientation=orientation)
    frame = orbit_frame(vol, file, up, view)
    tfn = make_tf(tf, vol, tf_range, threshold)
    az, el = orbit_angles(frame, None, None)
    data = ViewerData.create(vol, tfn, index=index, cell=cell, camera=CameraSpec(az, el), **frame)
    if not tf.lower().endswith(".json"):
        # Editable form of a preset: its colour map plus a few opacity points.
        data.tf = spec_from_preset(tf, tfn.value_range, threshold)
    server = ViewerServer(data, host, port, allow_remote=allow_remote)
    with err.status("preparing the index and kernels"):
        data.warm_up()
    if remote:
        warn(f"serving on {host}, reachable from other machines; the viewer has no authentication")
    out.print(f"sparsecast viewer: {server.url}  ({vol.name} {'x'.join(map(str, vol.dims))}; Ctrl-C stops)")
    if not no_browser:
        import threading
        import webbrowser

        opener = threading.Timer(0.5, webbrowser.open, args=(server.url,))
        opener.daemon = True
        opener.start()
    server.serve_forever()
