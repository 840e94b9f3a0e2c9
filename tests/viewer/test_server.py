"""The viewer's Starlette app through Starlette's TestClient (no sockets, no browser)."""

from __future__ import annotations

import io
import json
import sys

import numpy as np
import pytest

pytest.importorskip("starlette", reason="viewer extras not installed (pip install -e '.[view]')")
try:  # Starlette's TestClient needs httpx2 (newer Starlette) or httpx
    import httpx2  # noqa: F401
except ImportError:
    pytest.importorskip("httpx", reason="httpx2 or httpx needed by Starlette's TestClient")
from PIL import Image as PILImage  # noqa: E402
from starlette.testclient import TestClient  # noqa: E402
from starlette.websockets import WebSocketDisconnect  # noqa: E402

import sparsecast as sc  # noqa: E402
from sparsecast.errors import ParameterError  # noqa: E402
from sparsecast.viewer.server import LOOPBACK_HOSTS, check_host, create_app  # noqa: E402
from sparsecast.viewer.session import Session, ViewerData, tf_from_spec  # noqa: E402
from sparsecast.viewer.messages import RenderRequest, TFSpec  # noqa: E402

HOSTS = LOOPBACK_HOSTS + ("testserver",)


@pytest.fixture(scope="module")
def data():
    vol = sc.datasets.nbody_blobs(48, n_clusters=3, blobs_per_cluster=20, seed=5)
    return ViewerData.create(vol, "viridis")


@pytest.fixture(scope="module")
def client(data):
    with TestClient(create_app(data, allowed_hosts=HOSTS)) as c:
        yield c


def render_msg(seq=1, **kw):
    msg = {"type": "render", "seq": seq}
    msg.update(kw)
    return json.dumps(msg)


def recv_frame(ws):
    """Skip speedup updates; return (status, image array) of the next frame."""
    while True:
        msg = ws.receive_json()
        if msg["type"] == "speedup":
            continue
        assert msg["type"] == "frame", msg
        payload = ws.receive_bytes()
        img = PILImage.open(io.BytesIO(payload))
        assert img.format == msg["format"].upper()
        assert img.size == (msg["width"], msg["height"])
        return msg, np.asarray(img.convert("RGB"))


def recv_error(ws):
    while True:
        msg = ws.receive_json()
        if msg["type"] == "error":
            return msg
        assert msg["type"] == "speedup", msg


def test_page_and_static_files(client):
    r = client.get("/")
    assert r.status_code == 200 and "viewer.js" in r.text
    assert "Content-Security-Policy" in r.headers
    for name, ctype in [("viewer.js", "javascript"), ("interaction.js", "javascript"), ("viewer.css", "css"), ("index.html", "html")]:
        r = client.get(f"/static/{name}")
        assert r.status_code == 200 and ctype in r.headers["content-type"]
    # The page makes no external requests: no absolute URLs in what it loads.
    for name in ("index.html", "interaction.js", "viewer.js", "viewer.css"):
        text = client.get(f"/static/{name}").text
        assert "http://" not in text and "https://" not in text and "//cdn" not in text


@pytest.mark.parametrize("path", [
    "/static/../../pyproject.toml",
    "/static/..%2F..%2Fpyproject.toml",
    "/static/%2e%2e/%2e%2e/pyproject.toml",
    "/static/....//....//pyproject.toml",
    "/static//etc/passwd",
    "/static/%2Fetc%2Fpasswd",
    "/../pyproject.toml",
    "/pyproject.toml",
    "/static/server.py",
    "/static/../server.py",
    "/static/",
    "/etc/passwd",
])
def test_path_traversal_refused(client, path):
    r = client.get(path)
    assert r.status_code == 404
    assert "[project]" not in r.text and "root:" not in r.text


def test_foreign_host_and_origin_refused(data):
    with TestClient(create_app(data, allowed_hosts=HOSTS)) as c:
        assert c.get("/", headers={"host": "evil.example"}).status_code == 400
        with pytest.raises(WebSocketDisconnect):
            with c.websocket_connect("/ws", headers={"origin": "http://evil.example"}) as ws:
                ws.receive_json()
        # Own origin is fine.
        with c.websocket_connect("/ws", headers={"origin": "http://testserver"}) as ws:
            assert ws.receive_json()["type"] == "hello"


def test_check_host():
    assert check_host("127.0.0.1", False) is False
    assert check_host("::1", False) is False
    assert check_host("localhost", False) is False
    with pytest.raises(ParameterError, match="allow-remote"):
        check_host("0.0.0.0", False)
    assert check_host("0.0.0.0", True) is True


def test_hello_frames_tf_change_and_index_cache(client, data):
    with client.websocket_connect("/ws") as ws:
        hello = ws.receive_json()
        assert hello["type"] == "hello"
        assert hello["indices"] == ["auto", *sc.available_indices()]
        counts = hello["histogram"]["counts"]
        assert len(counts) == 128 and sum(counts) > 0
        assert hello["histogram"]["range"] == list(data.volume.value_range)
        assert set(hello["presets"]) == set(sc.PRESETS)
        state = hello["state"]

        cam = {"azimuth": 40, "elevation": 15, "zoom": 1.2}
        ws.send_text(render_msg(1, camera=cam, width=96, height=64, format="png", index={"name": "grid-pc", "cell": 8}))
        st1, im1 = recv_frame(ws)
        assert (st1["seq"], st1["width"], st1["height"], st1["index"]) == (1, 96, 64, "grid-pc")
        assert st1["rebuilt"] and st1["samples"] > 0 and st1["frame_ms"] >= 0 and st1["rebuild_ms"] >= 0
        assert im1.max() > 0  # something visible
        # What the page's clip-box overlay projects with: the frame's camera, the world box.
        assert set(st1["camera"]) == {"eye", "forward", "right", "up", "perspective"}
        assert hello["volume"]["bounds"] == [c.tolist() for c in data.volume.bounds]

        # Camera move: the index is reused.
        ws.send_text(render_msg(2, camera=dict(cam, azimuth=80), format="png"))
        st2, im2 = recv_frame(ws)
        assert not st2["rebuilt"] and st2["seq"] == 2 and (st2["width"], st2["height"]) == (96, 64)
        assert not np.array_equal(im1, im2)

        # TF change: new index, different frame.
        tf = dict(state["tf"])
        tf["points"] = [[0, 0, 0, 0, 0], [0.05, 1, 0, 0, 0.9], [1, 1, 1, 1, 1]]
        tf["colormap"] = None
        ws.send_text(render_msg(3, tf=tf, format="png"))
        st3, im3 = recv_frame(ws)
        assert st3["rebuilt"]
        assert not np.array_equal(im2, im3)

        # Preview frames are capped at 256 x 256, JPEG by default.
        ws.send_text(render_msg(4, width=1024, height=512, preview=True))
        st4, im4 = recv_frame(ws)
        assert (st4["width"], st4["height"], st4["preview"], st4["format"]) == (256, 128, True, "jpeg")
        assert im4.shape == (128, 256, 3)

        # Naive frames measure the speedup directly.
        ws.send_text(render_msg(5, width=64, height=64, index={"name": "naive"}))
        st5, _ = recv_frame(ws)
        assert st5["speedup_source"] == "measured" and st5["speedup"] == pytest.approx(1.0, rel=0.02)


def test_bad_messages_get_errors_and_socket_survives(client):
    with client.websocket_connect("/ws") as ws:
        assert ws.receive_json()["type"] == "hello"
        bad = [
            "not json",
            '{"type": "render", "width": NaN}',
            render_msg(width=10 ** 6, height=10 ** 6),
            render_msg(camera={"azimuth": "x", "elevation": 0, "zoom": 1}),
            render_msg(tf={"points": [[0, 0, 0, 0, 0]] * 1000, "colormap": None, "value_range": [0, 1]}),
            render_msg(index={"name": "/etc/passwd"}),
            render_msg(path="../../pyproject.toml"),
            json.dumps([1, 2]),
        ]
        for text in bad:
            ws.send_text(text)
            err = recv_error(ws)
            assert err["message"]
        ws.send_bytes(b"\x00\x01binary")
        assert "binary" in recv_error(ws)["message"]
        # The TF constructor rejects what the validator lets through (a span too small
        # for a table): an error reply naming the request, and the socket stays up.
        ws.send_text(render_msg(8, tf={"points": [[0, 0, 0, 0, 0], [1, 1, 1, 1, 1]], "colormap": None,
                                       "value_range": [0, 1e-310]}))
        err = recv_error(ws)
        assert err["seq"] == 8 and "value_range" in err["message"]
        ws.send_text(render_msg(9, width=32, height=32, tf={"points": [[0, 0, 0, 0, 0], [1, 1, 1, 1, 1]],
                                                          "colormap": "bone", "value_range": [0, 1]}))
        st, img = recv_frame(ws)
        assert st["seq"] == 9 and img.shape == (32, 32, 3)


def test_latest_request_wins(client):
    with client.websocket_connect("/ws") as ws:
        assert ws.receive_json()["type"] == "hello"
        n = 12
        for i in range(1, n + 1):
            ws.send_text(render_msg(i, camera={"azimuth": 10 * i, "elevation": 0, "zoom": 1}, width=128, height=128))
        seqs = []
        while not seqs or seqs[-1] != n:
            st, _ = recv_frame(ws)
            seqs.append(st["seq"])
        assert seqs == sorted(seqs) and seqs[-1] == n
        assert len(seqs) <= n


def test_session_tf_and_index_cache(data):
    s = Session(data)
    snap = s.update(RenderRequest(seq=1, width=40, height=30))
    _, st = s.render_frame(snap)
    _, st2 = s.render_frame(s.update(RenderRequest(seq=2)))
    assert st["rebuilt"] and not st2["rebuilt"]
    probe = s.probe_naive(snap, st["frame_ms"])
    assert probe["naive_ms"] > 0 and probe["speedup_source"] == "estimated"


def test_tf_from_spec_colormap_and_points():
    spec = TFSpec(((0.0, 0.2, 0.4, 0.6, 0.0), (0.5, 0.2, 0.4, 0.6, 0.0), (0.5, 0.2, 0.4, 0.6, 1.0),
                   (1.0, 0.2, 0.4, 0.6, 1.0)), None, (10.0, 20.0))
    tf = tf_from_spec(spec)
    assert tf.value_range == (10.0, 20.0)
    assert tf.is_empty(10.0, 14.9) and not tf.is_empty(15.1, 16.0)
    np.testing.assert_allclose(tf(18.0)[:3], [0.2, 0.4, 0.6], atol=1e-6)
    cm = tf_from_spec(TFSpec(spec.points, "magma", spec.value_range))
    assert cm.is_empty(10.0, 14.9) and not cm.is_empty(15.1, 16.0)
    assert not np.allclose(cm(18.0)[:3], [0.2, 0.4, 0.6])


def test_show_returns_inline_frame_handle():
    vol = sc.datasets.nbody_blobs(16, n_clusters=1, blobs_per_cluster=3, seed=1)
    h = sc.show(vol)
    try:
        assert h.url.startswith("http://127.0.0.1:")
        assert f'src="{h.url}"' in h._repr_html_()
        import urllib.request

        with urllib.request.urlopen(h.url, timeout=10) as r:
            assert b"viewer.js" in r.read()
    finally:
        h.stop()


def test_cli_view_rejects_remote_host_and_bad_port(monkeypatch, capsys):
    from sparsecast.cli import main

    for args, word in ([("view", "--host", "0.0.0.0"), "--allow-remote"], [("view", "--port", "70000"), "--port"]):
        monkeypatch.setattr(sys, "argv", ["sparsecast", *args])
        with pytest.raises(SystemExit) as info:
            main()
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert word in err and len(err.strip().splitlines()) == 1


def test_cli_view_starts_server(monkeypatch, capsys, tmp_path):
    from sparsecast.cli import main
    from sparsecast.viewer import server as server_mod

    vol = sc.datasets.nbody_blobs(16, n_clusters=1, blobs_per_cluster=3, seed=1)
    path = tmp_path / "v.npy"
    sc.save_volume(vol, path)
    seen = {}

    def fake_serve(self):
        seen["url"] = self.url
        self.sock.close()

    monkeypatch.setattr(server_mod.ViewerServer, "serve_forever", fake_serve)
    monkeypatch.setattr(sys, "argv", ["sparsecast", "view", str(path), "--port", "0", "--no-browser", "--tf", "magma"])
    try:
        main()
    except SystemExit as exc:  # typer's standalone mode exits 0
        assert not exc.code
    out = capsys.readouterr().out
    assert seen["url"].startswith("http://127.0.0.1:") and seen["url"] in out


def test_pan_moves_the_picture(client):
    with client.websocket_connect("/ws") as ws:
        ws.receive_json()
        cam = {"azimuth": 0, "elevation": 0, "zoom": 1.0}
        ws.send_text(render_msg(1, camera=cam, width=64, height=64, format="png"))
        _, centred = recv_frame(ws)
        ws.send_text(render_msg(2, camera=dict(cam, pan=[0.5, 0.0]), format="png"))
        _, panned = recv_frame(ws)
        # Panning the view right moves the content left: its brightness centroid shifts.
        cols = np.arange(64)
        cx0 = (centred.sum(axis=(0, 2)) * cols).sum() / centred.sum()
        cx1 = (panned.sum(axis=(0, 2)) * cols).sum() / panned.sum()
        assert cx1 < cx0 - 3


def test_session_caches_stay_bounded_over_many_tf_edits(data):
    """A long session of TF edits (each a new view) keeps its caches bounded, and
    closing the session (the client left) frees them."""
    import gc
    import tracemalloc

    from sparsecast.viewer.messages import IndexSpec
    from sparsecast.viewer.session import NAIVE_CACHE

    s = Session(data)
    base = s.tf

    def edit(i):
        pts = list(base.points)
        v, r, g, b, a = pts[-1]
        pts[-1] = (v, r, g, b, 0.2 + 0.6 * i / 5000)  # every edit a new view
        spec = TFSpec(tuple(pts), base.colormap, base.value_range)
        s.render_frame(s.update(RenderRequest(seq=i, tf=spec, index=IndexSpec("naive"), width=16, height=16)))

    for i in range(300):  # fills every cache (NAIVE_CACHE < 300)
        edit(i)
    gc.collect()
    tracemalloc.start()
    before = tracemalloc.take_snapshot()
    for i in range(300, 1500):
        edit(i)
    gc.collect()
    grown = sum(st.size_diff for st in tracemalloc.take_snapshot().compare_to(before, "filename"))
    tracemalloc.stop()
    assert len(s._naive_ms) <= NAIVE_CACHE
    assert grown < 400 * 1024, f"{grown} bytes kept by 1200 more TF edits"  # unbounded: ~740 kB
    s.close()
    assert not s._naive_ms and not s._indices and not s._tfs


def test_auto_index_cheap_while_the_tf_is_dragged(data):
    """The viewer's default is auto: a preview frame with a new TF (a point being
    dragged) gets the rebuild-cheap index, the full frame after it the fast one."""
    from sparsecast.index.auto import EDITING_INDEX, SPARSE_INDEX

    s = Session(data)
    assert s.index.name == "auto"
    _, st = s.render_frame(s.update(RenderRequest(seq=1, width=40, height=30)))
    assert st["index"] == SPARSE_INDEX and st["auto"]["reason"]
    pts = list(data.tf.points)
    pts[-1] = (*pts[-1][:4], 0.5)
    dragged = TFSpec(tuple(pts), data.tf.colormap, data.tf.value_range)
    _, st = s.render_frame(s.update(RenderRequest(seq=2, tf=dragged, preview=True)))
    assert st["index"] == EDITING_INDEX and st["auto"]["editing"]
    _, st = s.render_frame(s.update(RenderRequest(seq=3, preview=False)))
    assert st["index"] == SPARSE_INDEX
    # an orbit preview with the settled TF keeps the fast index
    _, st = s.render_frame(s.update(RenderRequest(seq=4, preview=True)))
    assert st["index"] == SPARSE_INDEX and not st["auto"]["editing"]


def _run_view(monkeypatch, capsys, *args):
    """``sparsecast view ARGS`` with the server's loop replaced; the ViewerData it served."""
    from sparsecast.cli import main
    from sparsecast.viewer import server as server_mod

    seen = {}

    def fake_serve(self):
        seen["data"] = self.app.state.viewer
        self.sock.close()

    monkeypatch.setattr(server_mod.ViewerServer, "serve_forever", fake_serve)
    monkeypatch.setattr(sys, "argv", ["sparsecast", "view", *map(str, args), "--port", "0", "--no-browser"])
    try:
        main()
    except SystemExit as exc:
        assert not exc.code, capsys.readouterr().err
    return seen["data"], capsys.readouterr().out


def test_cli_view_series_labels_and_iso(monkeypatch, capsys, tmp_path):
    steps = np.zeros((3, 12, 12, 12), np.float32)
    steps[:, 3:9, 3:9, 3:9] = np.arange(1, 4)[:, None, None, None]
    np.save(tmp_path / "run.npy", steps)
    data, out = _run_view(monkeypatch, capsys, tmp_path / "run.npy", "--time", "2", "--tf", "magma")
    assert data.series is not None and data.time == 2 and data.tf.value_range == (0.0, 3.0)
    assert data.hello()["series"]["steps"] == 3 and "3 steps" in out
    seg = np.zeros((10, 10, 10), np.uint8)
    seg[2:5, 2:5, 2:5], seg[5:8, 5:8, 5:8] = 3, 4
    np.save(tmp_path / "seg.npy", seg)
    data, out = _run_view(monkeypatch, capsys, tmp_path / "seg.npy", "--tf", "labels")
    assert data.labels.ids == (0, 3, 4) and data.labels.visible == (3, 4) and data.tf is None
    assert "3 label ids" in out
    data, _ = _run_view(monkeypatch, capsys, tmp_path / "run.npy", "--time", "0", "--mode", "iso", "--iso", "1.5")
    assert data.mode == "iso" and data.iso == (1.5,)


def test_cli_view_bad_mode_and_time_are_one_line(monkeypatch, capsys, tmp_path):
    from sparsecast.cli import main

    np.save(tmp_path / "v.npy", np.zeros((8, 8, 8), np.float32))
    for args, word in ([("--mode", "mip"), "--mode"], [("--iso", "0.5"), "--iso"], [("--time", "7"), "time"]):
        monkeypatch.setattr(sys, "argv", ["sparsecast", "view", str(tmp_path / "v.npy"), "--no-browser", *args])
        with pytest.raises(SystemExit) as info:
            main()
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert word in err and len(err.strip().splitlines()) == 1, err


def test_websocket_labels_and_time_round_trip():
    seg = np.zeros((16, 16, 16), np.uint8)
    seg[2:8, 2:8, 2:8], seg[8:14, 8:14, 8:14] = 1, 2
    data = ViewerData.create(sc.Volume(seg), sc.TransferFunction.labels([1, 2]))
    with TestClient(create_app(data, allowed_hosts=HOSTS)) as c, c.websocket_connect("/ws") as ws:
        hello = ws.receive_json()
        assert hello["labels"]["ids"] == [0, 1, 2] and hello["labels"]["counts"] == [16**3 - 2 * 216, 216, 216]
        ws.send_text(render_msg(1, width=32, height=32, format="png"))
        _, both = recv_frame(ws)
        ws.send_text(render_msg(2, labels={"visible": [1]}))
        _, one = recv_frame(ws)
        assert np.abs(both.astype(int) - one).max() > 20
        ws.send_text(render_msg(3, labels={"visible": [9]}))
        assert "id 9" in recv_error(ws)["message"]
        ws.send_text(render_msg(4, time=1))
        assert "not a time series" in recv_error(ws)["message"]
