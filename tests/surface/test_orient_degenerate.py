"""Meshes with a few zero-area faces render (no NaN, never hit); ``orient`` is a proper
rotation that makes any axis +z."""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast import Camera, surface
from sparsecast.axes import UP_AXES, axis_vector, up_rotation
from sparsecast.surface.mesh import (
    DEGENERATE_FRACTION, DegenerateFacesError, TriangleMesh, icosphere, orient, subdivide, z_up,
)


def sphere_with_degenerate(k: int) -> TriangleMesh:
    """A 5120-face sphere plus ``k`` zero-area faces: collinear corners in front of the sphere
    (where the orbit camera at azimuth 0 looks), alternating with repeated-vertex faces on it."""
    s = subdivide(icosphere(2), 2)
    v, f = s.vertices, s.faces
    extra_v, extra_f = [], []
    for i in range(k):
        if i % 2 == 0:
            n = len(v) + len(extra_v)
            x = -0.5 + i / max(k, 1)
            extra_v += [[x, -1.2, 0.0], [x + 0.1, -1.2, 0.0], [x + 0.3, -1.2, 0.0]]
            extra_f.append([n, n + 1, n + 2])
        else:
            a, b = f[i, 0], f[i, 1]
            extra_f.append([a, a, b])
    v = np.vstack([v, np.asarray(extra_v).reshape(-1, 3)])
    return TriangleMesh(v, np.vstack([f, extra_f]), f"sphere+{k}")


def test_a_few_degenerate_faces_are_kept_and_never_hit():
    m = sphere_with_degenerate(4)
    assert m.degenerate_faces.tolist() == [5120, 5121, 5122, 5123]
    cam = Camera.orbit(m, 0, 0)
    o, d = cam.rays(48, 48)
    for idx in (surface.build_bvh(m), surface.build_rbvh(m, "Q3")):
        for mode in ("shaded", "depth", "normal"):
            assert np.isfinite(surface.render_surface(idx, cam, 48, 48, mode=mode).rgba).all()
        h = surface.raycast(idx, o.reshape(-1, 3), d.reshape(-1, 3))
        assert h.hit.sum() > 500  # the sphere is there
        assert np.isfinite(h.points[h.hit]).all() and np.isfinite(h.normals[h.hit]).all()
        assert not np.isin(h.face[h.hit], m.degenerate_faces).any()


def test_many_degenerate_faces_are_an_error_naming_count_and_remedy():
    k = int(DEGENERATE_FRACTION * 5120) + 2  # just over 0.1 %
    with pytest.raises(DegenerateFacesError, match=rf"sphere\+{k}: {k} of {5120 + k} triangles are degenerate.*"
                                                    r"drop_degenerate=True") as info:
        sphere_with_degenerate(k)
    assert info.value.count == k and info.value.first == 5120
    mesh, dropped = TriangleMesh.cleaned(sphere_with_degenerate(4).vertices,
                                         np.vstack([subdivide(icosphere(2), 2).faces, [[0, 0, 1]] * k]))
    assert dropped == k and mesh.n_triangles == 5120 and mesh.degenerate_faces.size == 0


@pytest.mark.parametrize("up", UP_AXES)
def test_orient_is_a_rotation_taking_up_to_z(up):
    r = up_rotation(up)
    assert np.allclose(r @ r.T, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)
    assert np.array_equal(r @ axis_vector(up), [0.0, 0.0, 1.0])
    # An asymmetric mesh: a sphere pushed out along `up` ends up pushed out along +z.
    s = icosphere(2)
    v = s.vertices + 0.5 * np.maximum(s.vertices @ axis_vector(up), 0)[:, None] * axis_vector(up)
    m = TriangleMesh(v, s.faces, "bump")
    o = orient(m, up)
    assert o.bounds[1, 2] == pytest.approx(1.5) and o.bounds[0, 2] == pytest.approx(-1.0)
    # Normals turn with the vertices (winding kept: outward stays outward).
    np.testing.assert_allclose(o.face_normals, m.face_normals @ r.T, atol=1e-12)
    assert ((o.face_normals * (o.triangles.mean(axis=1) - o.center)).sum(axis=1) > 0).mean() > 0.99


def test_z_up_is_orient_y_and_faces_front_at_azimuth_zero():
    s = icosphere(1)
    v = s.vertices.copy()
    v[v[:, 2] > 0.5, 2] += 1.0  # a nose towards +z: the front of a y-up mesh
    m = TriangleMesh(v, s.faces, "nose")
    o = z_up(m)
    np.testing.assert_array_equal(o.vertices, orient(m, "y").vertices)
    np.testing.assert_array_equal(o.vertices, m.vertices[:, [0, 2, 1]] * [1.0, -1.0, 1.0])
    cam = Camera.orbit(o, 0, 0)
    nose = o.vertices[np.argmin(o.vertices[:, 1])]
    assert np.linalg.norm(cam.eye - nose) < np.linalg.norm(cam.eye - o.center)  # the nose faces the camera
    assert orient(m, "z") is m
