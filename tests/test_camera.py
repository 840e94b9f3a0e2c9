"""Cameras: framing, ray generation, and the Numba twin of Camera.rays."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.kernels.camera import primary_ray


@pytest.fixture(scope="module")
def vol():
    return sc.Volume(np.zeros((10, 20, 30), np.float32), spacing=(1.0, 0.5, 2.0), origin=(5, -3, 1))


def project(cam: sc.Camera, point, width=64, height=48):
    """Pixel coordinates of a world point (inverse of the ray generator)."""
    forward, right, up = cam.basis()
    p = cam.ray_params(width, height)
    rel = np.asarray(point, float) - cam.eye
    if cam.projection == "perspective":
        depth = rel @ forward
        u = (rel @ right) / depth / np.linalg.norm(p[6:9])
        v = (rel @ up) / depth / np.linalg.norm(p[9:12])
    else:
        u = (rel @ right) / np.linalg.norm(p[6:9])
        v = (rel @ up) / np.linalg.norm(p[9:12])
    return (u + 1) / 2 * width - 0.5, (1 - v) / 2 * height - 0.5


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
@pytest.mark.parametrize("az, el", [(0, 0), (30, 20), (90, 0), (180, -45), (0, 90), (0, -90), (270, 89.9)])
def test_orbit_frames_the_whole_volume(vol, projection, az, el):
    cam = sc.Camera.orbit(vol, az, el, projection=projection)
    # Centre of the volume projects to the image centre...
    cx, cy = project(cam, vol.center)
    assert cx == pytest.approx(31.5, abs=1e-6) and cy == pytest.approx(23.5, abs=1e-6)
    # ...and all eight corners are inside the image and in front of the eye.
    lo, hi = vol.bounds
    forward, _, _ = cam.basis()
    for corner in np.array(np.meshgrid(*zip(lo, hi))).T.reshape(-1, 3):
        x, y = project(cam, corner)
        assert -0.5 <= x <= 63.5 and -0.5 <= y <= 47.5
        assert (corner - cam.eye) @ forward > 0


def test_orbit_convention_z_up_x_right(vol):
    cam = sc.Camera.orbit(vol, 0, 0)
    forward, right, up = cam.basis()
    np.testing.assert_allclose(forward, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(right, [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(up, [0, 0, 1], atol=1e-12)


def test_screen_up_is_continuous_through_the_pole(vol):
    _, _, up_near = sc.Camera.orbit(vol, 40, 89.999).basis()
    _, _, up_pole = sc.Camera.orbit(vol, 40, 90).basis()
    np.testing.assert_allclose(up_near, up_pole, atol=1e-3)


@given(
    az=st.floats(-360, 360), el=st.floats(-90, 90),
    projection=st.sampled_from(["perspective", "orthographic"]),
    w=st.integers(1, 17), h=st.integers(1, 17),
)
def test_numba_rays_match_numpy_rays(az, el, projection, w, h):
    vol = sc.Volume(np.zeros((3, 4, 5), np.uint8))
    cam = sc.Camera.orbit(vol, az, el, projection=projection)
    o, d = cam.rays(w, h)
    params = cam.ray_params(w, h)
    for py in range(h):
        for px in range(w):
            ray = primary_ray(params, px, py, w, h)
            np.testing.assert_allclose(ray[:3], o[py, px], atol=1e-9)
            np.testing.assert_allclose(ray[3:], d[py, px], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)


def test_orthographic_rays_are_parallel_perspective_share_an_origin(vol):
    o, d = sc.Camera.orbit(vol, 10, 10, projection="orthographic").rays(8, 6)
    assert np.allclose(d, d[0, 0])
    assert not np.allclose(o, o[0, 0])
    o, d = sc.Camera.orbit(vol, 10, 10, projection="perspective").rays(8, 6)
    assert np.allclose(o, o[0, 0])
    assert not np.allclose(d, d[0, 0])


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"eye": (0, 0, 0), "target": (0, 0, 0)}, "target - eye"),
        ({"eye": (0, 0, 0), "target": (0, 0, 1), "up": (0, 0, 2)}, "up"),
        ({"eye": (0, 0, np.nan), "target": (0, 0, 1)}, "eye"),
        ({"eye": (0, 0, 0), "target": (0, 1, 0), "fov_y": 180}, "fov_y"),
        ({"eye": (0, 0, 0), "target": (0, 1, 0), "projection": "fisheye"}, "projection"),
        ({"eye": (0, 0, 0), "target": (0, 1, 0), "ortho_height": 0}, "ortho_height"),
    ],
)
def test_bad_cameras_are_rejected(kwargs, name):
    with pytest.raises(sc.ParameterError, match=name):
        sc.Camera.look_at(**kwargs)


def test_orbit_rejects_bad_zoom(vol):
    with pytest.raises(sc.ParameterError, match="zoom"):
        sc.Camera.orbit(vol, zoom=0)
    with pytest.raises(sc.ParameterError, match="azimuth"):
        sc.Camera.orbit(vol, azimuth=np.inf)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_orbit_pan_shifts_the_view(vol, projection):
    cam = sc.Camera.orbit(vol, 30, 20, projection=projection, pan=(0.5, -0.25))
    _, right, up = cam.basis()
    radius = vol.diagonal / 2
    np.testing.assert_allclose(cam.target, vol.center + radius * (0.5 * right - 0.25 * up), atol=1e-9)
    x, y = project(cam, vol.center)
    assert x < 31.5 and y < 23.5  # centre moved left and up on screen
    with pytest.raises(sc.ParameterError, match="pan"):
        sc.Camera.orbit(vol, pan=(np.nan, 0))


def test_azimuth_moves_the_camera_clockwise_seen_from_above():
    """As the module docstring says: azimuth 0 looks along +y, azimuth 90 along +x."""
    import numpy as np

    import sparsecast as sc

    vol = sc.Volume(np.zeros((8, 8, 8), np.float32))
    to_eye = [sc.Camera.orbit(vol, az, 0).eye - vol.center for az in (0, 90)]
    np.testing.assert_allclose(to_eye[0] / np.linalg.norm(to_eye[0]), [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(to_eye[1] / np.linalg.norm(to_eye[1]), [-1, 0, 0], atol=1e-12)
    assert np.cross(to_eye[0], to_eye[1])[2] < 0  # clockwise about +z
