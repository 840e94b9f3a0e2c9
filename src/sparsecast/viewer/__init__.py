"""Interactive viewer: a local web page that orbits a volume and edits its TF live,
with render mode and isovalue, a clip box (sliders and face handles over the image),
up to 6 clip planes (rows with enable / normal / flip / remove / offset, and centre and
normal-tip handles over the image), a label table (label volumes) and a time slider
(series).

``sparsecast view FILE`` (the CLI) or :func:`show` (Jupyter). The web stack
(Starlette, uvicorn) is an optional dependency: ``pip install "sparsecast[view]"``.
It is imported only when a server is created.

Modules: :mod:`.messages` (validation of client messages), :mod:`.session` (per-client
state, index cache, frame rendering), :mod:`.server` (Starlette app, uvicorn runner),
``static/`` (the page: HTML, JS, CSS; no build step, no external requests;
``static/interaction.js`` holds every pointer and overlay mapping as pure functions,
tested under node).
"""

from __future__ import annotations

from typing import Any

__all__ = ["show", "require_web_stack"]

_SERVERS: list[Any] = []  # keep background servers alive for the process


def require_web_stack() -> None:
    """Raise a one-line ParameterError when the optional web dependencies are missing."""
    from ..errors import ParameterError

    missing = []
    for mod in ("starlette", "uvicorn", "websockets"):
        try:
            __import__(mod)
        except ImportError:
            missing.append(mod)
    if missing:
        raise ParameterError(
            f"the viewer needs {', '.join(missing)}; install them with: pip install \"sparsecast[view]\""
        )


class ViewerHandle:
    """What :func:`show` returns: displays as an inline frame in Jupyter; ``url``; ``stop()``."""

    def __init__(self, server, width: int, height: int) -> None:
        self.server = server
        self.url = server.url
        self.width = width
        self.height = height

    def _repr_html_(self) -> str:
        return (f'<iframe src="{self.url}" width="{self.width}" height="{self.height}" '
                f'style="border:0" title="sparsecast viewer"></iframe>')

    def stop(self) -> None:
        self.server.stop()
        if self.server in _SERVERS:
            _SERVERS.remove(self.server)

    def __repr__(self) -> str:
        return f"<sparsecast viewer at {self.url}>"


def show(volume, tf=None, *, index: str | None = None, cell: int | None = None, time: int = 0,
         mode: str = "dvr", iso=None, port: int = 0, width: int = 1000, height: int = 740) -> ViewerHandle:
    """Start a viewer for ``volume`` on 127.0.0.1 in a background thread and return a
    handle that Jupyter displays as an inline frame.

    The page has the controls of ``sparsecast view``: TF editor, index, render mode
    with an isovalue slider, clip box sliders, a label table for a label volume and a
    time slider for a series.

    Parameters
    ----------
    volume : Volume, VolumeSeries or ndarray
        A 3-D array ``(nz, ny, nx)`` is one volume; a 4-D array ``(t, nz, ny, nx)`` or a
        :class:`~sparsecast.series.VolumeSeries` is a time series (a time slider).
    tf : TransferFunction, LabelTransferFunction or preset name, optional
        Initial TF (default: the ``viridis`` preset over the value range, of every step
        for a series). A label TF shows the volume as a label volume: a table of its
        ids (visibility, colour, voxel count).
    index, cell : optional
        Initial index (default ``auto``) and grid cell size.
    time : int
        Initial step of a series.
    mode : {"dvr", "iso", "iso+dvr"}
        Initial render mode.
    iso : float or sequence of float, optional
        Initial isovalues in data units (default: the middle of the value range).
    port : int
        0 picks a free port.
    width, height : int
        Size of the inline frame in pixels.
    """
    import numpy as np

    from ..series import VolumeSeries
    from ..volume import Volume

    require_web_stack()
    from .server import ViewerServer
    from .session import ViewerData

    if isinstance(volume, np.ndarray):
        volume = VolumeSeries.from_array(volume) if volume.ndim == 4 else Volume(volume)
    kw = {} if iso is None else {"iso": tuple(float(v) for v in np.atleast_1d(iso))}
    data = ViewerData.create(volume, tf, index=index, cell=cell, time=time, mode=mode, **kw)
    server = ViewerServer(data, "127.0.0.1", port).start()
    _SERVERS.append(server)
    return ViewerHandle(server, width, height)
