"""render_surface images: shading modes, the BVH and the RBVH agreeing, bad parameters."""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast import Camera
from sparsecast.errors import ParameterError
from sparsecast.surface import build_bvh, build_rbvh, render_surface
from sparsecast.surface.mesh import icosphere


@pytest.fixture(scope="module")
def sphere():
    return icosphere(4)


def test_modes_and_agreement_between_indices(sphere):
    cam = Camera.orbit(sphere, 30, 20)
    exact = render_surface(build_bvh(sphere), cam, 64, 48)
    approx = render_surface(build_rbvh(sphere, "Q2"), cam, 64, 48)
    assert exact.rgba.shape == (48, 64, 4) and exact.stats["index"] == "bvh"
    assert exact.stats["rays"] == 64 * 48 and 0 < exact.stats["hits"] < 64 * 48
    # The sphere is in the middle, the corners are background.
    assert exact.rgba[24, 32, 0] > 0.5 and exact.rgba[0, 0, 0] == 0.0
    mse = np.mean((exact.rgba[..., :3] - approx.rgba[..., :3]) ** 2)
    assert 10 * np.log10(1.0 / max(mse, 1e-12)) > 30.0
    normal = render_surface(build_bvh(sphere), cam, 64, 48, mode="normal")
    # Facing the camera at the centre: the normal is -forward.
    fwd, _, _ = cam.basis()
    np.testing.assert_allclose(normal.rgba[24, 32, :3] * 2 - 1, -fwd, atol=0.1)
    depth = render_surface(build_bvh(sphere), cam, 64, 48, mode="depth")
    assert depth.rgba[24, 32, 0] > depth.rgba[24, 22, 0] > 0  # the centre is nearest


def test_bad_render_parameters(sphere):
    index = build_bvh(sphere)
    cam = Camera.orbit(sphere)
    with pytest.raises(ParameterError, match="mode"):
        render_surface(index, cam, 8, 8, mode="xray")
    with pytest.raises(ParameterError, match="width"):
        render_surface(index, cam, 0, 8)
    with pytest.raises(ParameterError, match="camera"):
        render_surface(index, "cam", 8, 8)
