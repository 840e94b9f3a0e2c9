"""The viewer's Host check (issue 14, item 13): a malformed Host header matches no host."""

from __future__ import annotations

import pytest

pytest.importorskip("starlette")

from sparsecast.viewer.server import _host_only  # noqa: E402


@pytest.mark.parametrize("header, host", [
    ("127.0.0.1", "127.0.0.1"), ("127.0.0.1:8765", "127.0.0.1"), ("LOCALHOST:80", "localhost"),
    ("[::1]:8765", "::1"), ("[::1]", "::1"), ("testserver", "testserver"),
    ("127.0.0.1:8765, evil.example", ""), ("127.0.0.1:evil.example", ""), ("127.0.0.1 evil", ""),
    ("127.0.0.1:８７６５", ""), ("", ""), ("[::1", ""), ("a:1:2", ""),
])
def test_host_part(header, host):
    assert _host_only(header) == host


def test_malformed_host_is_refused_by_the_app():
    from starlette.testclient import TestClient

    import sparsecast as sc
    from sparsecast.viewer.server import LOOPBACK_HOSTS, create_app
    from sparsecast.viewer.session import ViewerData

    data = ViewerData.create(sc.datasets.nbody_blobs(16, n_clusters=1, blobs_per_cluster=2, seed=1), "viridis")
    with TestClient(create_app(data, allowed_hosts=LOOPBACK_HOSTS)) as c:
        assert c.get("/", headers={"host": "127.0.0.1:8765"}).status_code == 200
        for bad in ("127.0.0.1:8765, evil.example", "127.0.0.1:evil.example"):
            assert c.get("/", headers={"host": bad}).status_code == 400
