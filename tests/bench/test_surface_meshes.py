"""The surface bench's large scenes: copies side by side are disjoint, turned, and complete."""

from __future__ import annotations

import numpy as np

from sparsecast.bench.surface import MESHES, side_by_side
from sparsecast.surface.mesh import icosphere


def test_side_by_side_copies_are_disjoint_turned_and_complete():
    mesh = icosphere(2)
    mesh = type(mesh)(mesh.vertices * np.array([2.0, 1.0, 1.0]), mesh.faces, "ellipsoid")  # turns show
    out = side_by_side(mesh, 3, 2)
    n_v, n_f = len(mesh.vertices), len(mesh.faces)
    assert out.n_triangles == 6 * n_f and len(out.vertices) == 6 * n_v
    boxes = []
    for k in range(6):
        v = out.vertices[k * n_v:(k + 1) * n_v]
        np.testing.assert_array_equal(out.faces[k * n_f:(k + 1) * n_f] - k * n_v, mesh.faces)
        # A rigid copy: same edge lengths as the original.
        e0 = np.linalg.norm(np.diff(mesh.vertices[mesh.faces[:, :2]], axis=1), axis=2)
        e1 = np.linalg.norm(np.diff(v[mesh.faces[:, :2]], axis=1), axis=2)
        np.testing.assert_allclose(e1, e0, atol=1e-9)
        boxes.append((v.min(axis=0), v.max(axis=0)))
    for a in range(6):
        for b in range(a + 1, 6):
            (lo_a, hi_a), (lo_b, hi_b) = boxes[a], boxes[b]
            assert np.any(hi_a[:2] < lo_b[:2]) or np.any(hi_b[:2] < lo_a[:2])
    # Each copy is turned differently: the x extents of the ellipsoid's copies differ.
    widths = [hi[0] - lo[0] for lo, hi in boxes]
    assert np.ptp(widths) > 0.1


def test_large_scenes_are_registered_and_need_the_shared_data():
    for name in ("turbine", "dragon", "dragon-3.5m", "dragons-7m"):
        assert MESHES[name][1] is True
