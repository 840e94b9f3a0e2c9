"""The viewer's web server: Starlette app (static page + one WebSocket) and uvicorn runner.

Security: binds to 127.0.0.1 unless told otherwise (:func:`check_host`); serves only
the files of ``sparsecast/viewer/static`` (read once at start-up into memory, looked
up by exact name: no path from a client is ever opened); accepts WebSocket connections
only from its own page (the ``Origin`` header, when present, must match the ``Host``);
only loopback ``Host`` headers when bound to loopback (DNS rebinding); validates every
message (:mod:`.messages`).

Render loop (per connection): received messages update the session state at once;
a render request goes into a one-slot "pending" box that later requests overwrite, and
one task renders the latest request in a worker thread (``asyncio.to_thread``), so a
dragging client never queues up work: stale requests are dropped, the latest wins.
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import re
import socket
import threading
import time
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

from ..errors import ParameterError, SparsecastError
from ..transfer import PRESETS
from .messages import MessageError, parse_message
from .session import Session, Snapshot, ViewerData, viewer_indices

__all__ = ["create_app", "check_host", "ViewerServer", "LOOPBACK_HOSTS", "IDLE_PROBE_S"]

LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")
#: Seconds of idleness after a full frame before the naive-speed probe runs.
IDLE_PROBE_S = 1.0

_CONTENT_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
}
_SECURITY_HEADERS = {
    "Content-Security-Policy": (
        "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; "
        "connect-src 'self' ws: wss:; frame-ancestors *"
    ),
    "X-Content-Type-Options": "nosniff",
    "Cache-Control": "no-store",
    "Referrer-Policy": "no-referrer",
}


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_host(host: str, allow_remote: bool) -> bool:
    """Validate the bind address; returns True when it is not loopback (warn then)."""
    if is_loopback(host):
        return False
    if not allow_remote:
        raise ParameterError(
            f"--host: {host!r} is not a loopback address; the viewer has no authentication, "
            "so binding elsewhere needs --allow-remote"
        )
    return True


def _load_static() -> dict[str, tuple[bytes, str]]:
    files = {}
    root = resources.files("sparsecast.viewer") / "static"
    for name in ("index.html", "interaction.js", "viewer.js", "viewer.css"):
        suffix = name[name.rfind("."):]
        files[name] = ((root / name).read_bytes(), _CONTENT_TYPES[suffix])
    return files


#: a Host header: a name or IPv4 address, or an IPv6 address in brackets, then an
#: optional ASCII port; anything else (a list, a port that is not a number) matches nothing
_HOST_RE = re.compile(r"(?:\[(?P<v6>[0-9a-f:.]+)\]|(?P<name>[a-z0-9.-]+))(?::[0-9]{1,5})?", re.ASCII)


def _host_only(value: str) -> str:
    """The host part of a ``Host`` header, or ``""`` when the header is malformed
    (``127.0.0.1:8765, evil.example`` and ``127.0.0.1:evil.example`` are)."""
    m = _HOST_RE.fullmatch(value.strip().lower())
    if m is None:
        return ""
    return m.group("v6") or m.group("name")


def create_app(data: ViewerData, *, allow_remote: bool = False, allowed_hosts: tuple[str, ...] | None = None):
    """The Starlette application serving ``data`` (one volume) to any number of clients."""
    from starlette.applications import Starlette
    from starlette.requests import Request
    from starlette.responses import PlainTextResponse, Response
    from starlette.routing import Route, WebSocketRoute
    from starlette.websockets import WebSocket, WebSocketDisconnect

    static = _load_static()
    hosts = None if allow_remote else tuple(allowed_hosts or LOOPBACK_HOSTS)

    def host_ok(headers) -> bool:
        if hosts is None:
            return True
        return _host_only(headers.get("host", "")) in hosts

    def not_found() -> Response:
        return PlainTextResponse("not found", status_code=404, headers=_SECURITY_HEADERS)

    async def page(request: Request) -> Response:
        if not host_ok(request.headers):
            return PlainTextResponse("bad host", status_code=400)
        body, ctype = static["index.html"]
        return Response(body, media_type=ctype, headers=_SECURITY_HEADERS)

    async def static_file(request: Request) -> Response:
        if not host_ok(request.headers):
            return PlainTextResponse("bad host", status_code=400)
        # Looked up by exact name among the files loaded at start-up; nothing is opened.
        entry = static.get(request.path_params["name"])
        if entry is None:
            return not_found()
        body, ctype = entry
        return Response(body, media_type=ctype, headers=_SECURITY_HEADERS)

    async def fallback(request: Request) -> Response:
        return not_found()

    async def ws_endpoint(ws: WebSocket) -> None:
        origin = ws.headers.get("origin")
        if not host_ok(ws.headers) or (
            origin is not None and not allow_remote and urlsplit(origin).netloc.lower() != ws.headers.get("host", "").lower()
        ):
            await ws.close(code=1008)
            return
        await ws.accept()
        session = Session(data)
        send_lock = asyncio.Lock()
        pending: list[Snapshot | None] = [None]
        wake = asyncio.Event()
        indices = viewer_indices()
        label_ids = None if data.labels is None else data.labels.ids
        steps = 0 if data.series is None else len(data.series)

        async def send_json(obj: dict) -> None:
            async with send_lock:
                await ws.send_text(json.dumps(obj))

        async def render_loop() -> None:
            probe_for: tuple[Snapshot, float] | None = None
            while True:
                if probe_for is not None:
                    try:
                        await asyncio.wait_for(wake.wait(), IDLE_PROBE_S)
                    except asyncio.TimeoutError:
                        s, ms = probe_for
                        probe_for = None
                        if pending[0] is None and session.needs_probe(s):
                            try:
                                await send_json(await asyncio.to_thread(session.probe_naive, s, ms))
                            except SparsecastError:
                                pass
                        continue
                else:
                    await wake.wait()
                wake.clear()
                snap, pending[0] = pending[0], None  # latest request wins
                if snap is None:
                    continue
                try:
                    payload, status = await asyncio.to_thread(session.render_frame, snap)
                except SparsecastError as exc:
                    await send_json({"type": "error", "seq": snap.seq, "message": str(exc)})
                    continue
                status["dropped"] = session_dropped[0]
                async with send_lock:
                    await ws.send_text(json.dumps(status))
                    await ws.send_bytes(payload)
                probe_for = (snap, status["frame_ms"]) if session.needs_probe(snap) else None

        session_dropped = [0]
        await send_json(data.hello())
        task = asyncio.create_task(render_loop())
        try:
            while True:
                msg = await ws.receive()
                if msg["type"] == "websocket.disconnect":
                    break
                if task.done():
                    break
                try:
                    req = parse_message(msg.get("text") if msg.get("text") is not None else msg.get("bytes"),
                                        indices=indices, presets=PRESETS, label_ids=label_ids, steps=steps)
                except MessageError as exc:
                    await send_json({"type": "error", "message": str(exc)})
                    continue
                if pending[0] is not None:
                    session_dropped[0] += 1
                pending[0] = session.update(req)
                wake.set()
        except WebSocketDisconnect:
            pass
        finally:
            task.cancel()
            try:
                await task
            except (asyncio.CancelledError, Exception):
                pass
            session.close()  # free its indices and caches now, not when the socket object dies

    routes = [
        Route("/", page),
        Route("/static/{name}", static_file),
        WebSocketRoute("/ws", ws_endpoint),
        Route("/{rest:path}", fallback),
    ]
    app = Starlette(routes=routes)
    app.state.viewer = data
    return app


class ViewerServer:
    """uvicorn serving :func:`create_app` on ``host:port`` (0: a free port).

    ``serve_forever()`` blocks (the CLI); ``start()`` runs it in a daemon thread and
    returns once it accepts connections (Jupyter, tests); ``stop()`` shuts it down.
    """

    def __init__(self, data: ViewerData, host: str = "127.0.0.1", port: int = 0, *,
                 allow_remote: bool = False, log_level: str = "warning") -> None:
        import uvicorn

        if not 0 <= int(port) <= 65535:
            raise ParameterError(f"--port: expected 0..65535, got {port}")
        check_host(host, allow_remote)
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        # Each frame is two WebSocket messages (status, image): without TCP_NODELAY the
        # second waits for the client's delayed ACK of the first (~40 ms on Linux).
        # Linux passes the option on to accepted connections.
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        try:
            self.sock.bind((host, int(port)))
        except OSError as exc:
            self.sock.close()
            raise ParameterError(f"--port: cannot listen on {host}:{port} ({exc.strerror or exc})") from None
        self.host = host
        self.port = self.sock.getsockname()[1]
        self.app = create_app(data, allow_remote=allow_remote)
        from uvicorn.config import WS_PROTOCOLS

        # The sans-I/O websockets implementation where this uvicorn has it (no deprecation).
        ws = "websockets-sansio" if "websockets-sansio" in WS_PROTOCOLS else "auto"
        config = uvicorn.Config(self.app, log_level=log_level, ws=ws, lifespan="off",
                                ws_max_size=256 * 1024)
        self.server = uvicorn.Server(config)
        self.thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        h = self.host
        if h in ("0.0.0.0", "::"):
            h = "127.0.0.1"
        if ":" in h:
            h = f"[{h}]"
        return f"http://{h}:{self.port}/"

    def serve_forever(self) -> None:
        self.server.run(sockets=[self.sock])

    def start(self, timeout: float = 10.0) -> "ViewerServer":
        self.thread = threading.Thread(target=self.serve_forever, name=f"sparsecast-viewer-{self.port}", daemon=True)
        self.thread.start()
        t0 = time.monotonic()
        while not self.server.started:
            if not self.thread.is_alive() or time.monotonic() - t0 > timeout:
                raise RuntimeError("viewer server did not start")
            time.sleep(0.02)
        return self

    def stop(self, timeout: float = 5.0) -> None:
        self.server.should_exit = True
        if self.thread is not None:
            self.thread.join(timeout)
        try:
            self.sock.close()
        except OSError:
            pass

    def _repr_html_(self) -> str:
        return f'<a href="{self.url}">{self.url}</a>'


def describe(data: ViewerData) -> dict[str, Any]:
    return data.hello()
