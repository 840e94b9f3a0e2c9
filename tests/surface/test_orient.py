"""orient_points: the named up axis becomes +z by a proper rotation; y agrees with z_up."""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast.errors import ParameterError
from sparsecast.surface.mesh import UP_AXES, PointCloud, icosphere, orient_points, up_rotation, z_up

AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1), "-x": (-1, 0, 0), "-y": (0, -1, 0), "-z": (0, 0, -1)}


@pytest.mark.parametrize("up", UP_AXES)
def test_rotation_takes_the_axis_to_z(rng, up):
    r = up_rotation(up)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)  # no mirror: windings and normals keep their side
    np.testing.assert_allclose(r @ np.array(AXES[up], float), [0, 0, 1])
    pts = rng.normal(size=(50, 3))
    nrm = rng.normal(size=(50, 3))
    cloud = PointCloud(pts, nrm, 0.1, "c", normals_estimated=True)
    out = orient_points(cloud, up)
    np.testing.assert_allclose(out.points, pts @ r.T)
    np.testing.assert_allclose(out.normals, cloud.normals @ r.T)
    np.testing.assert_allclose(out.points @ [0, 0, 1], pts @ np.array(AXES[up], float))  # height = old up
    assert out.normals_estimated and np.all(out.radii == 0.1) and out.source == "c"


def test_y_matches_z_up_of_meshes():
    mesh = icosphere(1)
    cloud = orient_points(PointCloud(mesh.vertices, None, 0.1), "y")
    np.testing.assert_allclose(cloud.points, z_up(mesh).vertices)
    assert orient_points(PointCloud(mesh.vertices, None, 0.1), "z").normals is None


def test_unknown_axis():
    with pytest.raises(ParameterError, match="up: expected one of x, y, z"):
        up_rotation("w")
