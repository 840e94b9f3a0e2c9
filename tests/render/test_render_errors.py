"""Bad input to ``render()`` and the objects it takes: one clear error each.
"""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast import Camera, ParameterError, TransferFunction, TransferFunctionError, Volume, VolumeDataError
from render_helpers import assert_matches_reference


# ---------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "width, height, name",
    [
        (0, 8, "width"), (8, 0, "height"), (-3, 8, "width"), (8, -1, "height"),
        (8.5, 8, "width"), (8, 7.0, "height"), ("8", 8, "width"), (True, 8, "width"),
        (None, 8, "width"),
        (100000, 8, "width"), (8, 100000, "height"), (20000, 20000, "width"),
        (16384, 16384, "image size"), (10000, 10000, "image size"),
    ],
)
def test_bad_image_size(small, width, height, name):
    vol, tf, cam = small
    with pytest.raises(ParameterError, match=name):
        sc.render(vol, tf, cam, width, height)


def test_numpy_integer_size_ok(small):
    vol, tf, cam = small
    img = sc.render(vol, tf, cam, np.int64(5), np.int32(3))
    assert img.rgba.shape == (3, 5, 4)


@pytest.mark.parametrize("dt", [0.0, -0.5, float("nan"), float("inf"), -float("inf"), 1e-9, 1e-300])
def test_bad_dt(small, dt):
    vol, tf, cam = small
    with pytest.raises(ParameterError, match="dt"):
        sc.render(vol, tf, cam, 8, 8, dt=dt)


@pytest.mark.parametrize("ert", [0.0, -0.1, 1.0000001, 2.0, float("nan"), float("inf")])
def test_bad_ert(small, ert):
    vol, tf, cam = small
    with pytest.raises(ParameterError, match="ert"):
        sc.render(vol, tf, cam, 8, 8, ert=ert)


def test_unknown_index(small):
    vol, tf, cam = small
    with pytest.raises(ParameterError, match="index") as exc:
        sc.render(vol, tf, cam, 8, 8, index="octree-of-doom")
    assert "octree-of-doom" in str(exc.value) and "naive" in str(exc.value)
    with pytest.raises(ParameterError, match="index"):
        sc.build_index(vol, tf, "octree-of-doom")


def test_unknown_preset():
    with pytest.raises(TransferFunctionError, match="preset") as exc:
        TransferFunction.preset("no-such-map", (0.0, 1.0))
    assert "no-such-map" in str(exc.value) and "viridis" in str(exc.value)


@pytest.mark.parametrize("bg", ["purple", (1.0, 2.0, 0.0), (0.1, 0.2), (0.1, 0.2, 0.3, 0.4, 0.5),
                                (float("nan"), 0.0, 0.0), (-0.1, 0.0, 0.0, 1.0)])
def test_unknown_background(small, bg):
    vol, tf, cam = small
    with pytest.raises(ParameterError, match="background"):
        sc.render(vol, tf, cam, 8, 8, background=bg)


def test_prebuilt_index_with_other_tf(small):
    vol, tf, cam = small
    idx = sc.build_index(vol, tf, "naive")
    other = TransferFunction.preset("magma", (0.0, 1.0))
    with pytest.raises(ParameterError, match="index"):
        sc.render(vol, other, cam, 8, 8, index=idx)
    other_vol = Volume(np.array(vol.data))
    with pytest.raises(ParameterError, match="index"):
        sc.render(other_vol, tf, cam, 8, 8, index=idx)
    # the right pair is accepted and gives the same image as building on the fly
    a = sc.render(vol, tf, cam, 8, 8, index=idx)
    b = sc.render(vol, tf, cam, 8, 8)
    np.testing.assert_array_equal(a.rgba, b.rgba)


def test_bad_render_argument_types(small):
    vol, tf, cam = small
    with pytest.raises(ParameterError, match="tf"):
        sc.render(vol, "viridis", cam, 8, 8)
    with pytest.raises(ParameterError, match="camera"):
        sc.render(vol, tf, None, 8, 8)
    with pytest.raises(ParameterError, match="volume"):
        sc.render([1, 2, 3], tf, cam, 8, 8)


def test_volume_nan_rejected_and_replaced(rng):
    data = rng.random((5, 6, 7)).astype(np.float32)
    data[1, 2, 3] = np.nan
    data[4, 0, 0] = np.inf
    data[0, 5, 6] = -np.inf
    with pytest.raises(VolumeDataError, match="NaN") as exc:
        Volume(data, name="probe")
    assert "probe" in str(exc.value) and "nonfinite" in str(exc.value)
    vol = Volume(data, nonfinite="replace")
    finite = data[np.isfinite(data)]
    assert np.all(np.isfinite(vol.data))
    assert vol.data[1, 2, 3] == finite.min()
    assert vol.data[4, 0, 0] == finite.max()
    assert vol.data[0, 5, 6] == finite.min()
    tf = TransferFunction.preset("viridis", vol.value_range)
    assert_matches_reference(vol, tf, Camera.orbit(vol, 10, 10), 9, 9, dt=0.5)
    with pytest.raises(ParameterError, match="nonfinite"):
        Volume(data, nonfinite="ignore")
    with pytest.raises(VolumeDataError, match="NaN"):
        Volume(np.full((2, 2, 2), np.nan, np.float32), nonfinite="replace")


@pytest.mark.parametrize("shape", [(0, 4, 4), (4, 0, 4), (4, 4, 0)])
def test_zero_size_volume(shape):
    with pytest.raises(VolumeDataError, match="zero-size"):
        Volume(np.zeros(shape, np.float32))


@pytest.mark.parametrize("shape", [(4, 4), (4,), (2, 2, 2, 2), ()])
def test_volume_wrong_ndim(shape):
    with pytest.raises(VolumeDataError, match="3-D"):
        Volume(np.zeros(shape, np.float32))


@pytest.mark.parametrize("dtype", ["complex64", "U3", "object"])
def test_volume_unsupported_dtype(dtype):
    data = np.zeros((2, 3, 4), dtype=dtype)
    with pytest.raises(VolumeDataError, match="dtype"):
        Volume(data, name="probe")


@pytest.mark.parametrize(
    "kw, name",
    [
        (dict(eye=(1, 2, 3), target=(1, 2, 3)), "eye"),
        (dict(eye=(0, 0, 0), target=(0, 0, 5), up=(0, 0, 1)), "up"),
        (dict(eye=(0, 0, 0), target=(0, 0, 5), up=(0, 0, -3)), "up"),
        (dict(eye=(0, 0, 0), target=(1, 0, 0), up=(0, 0, 0)), "up"),
        (dict(eye=(0, 0, float("nan")), target=(1, 0, 0)), "eye"),
        (dict(eye=(0, 0), target=(1, 0, 0)), "eye"),
    ],
)
def test_bad_camera(kw, name):
    with pytest.raises(ParameterError, match=name):
        Camera.look_at(**kw)


def test_bad_camera_parameters(small):
    vol = small[0]
    with pytest.raises(ParameterError, match="projection"):
        Camera.orbit(vol, 0, 0, projection="fisheye")
    with pytest.raises(ParameterError, match="fov_y"):
        Camera.look_at((0, 0, 0), (1, 0, 0), fov_y=180.0)
    with pytest.raises(ParameterError, match="zoom"):
        Camera.orbit(vol, 0, 0, zoom=0.0)
    with pytest.raises(ParameterError, match="azimuth"):
        Camera.orbit(vol, float("nan"), 0)





@pytest.mark.parametrize("kw, name", [(dict(dt="fast"), "dt"), (dict(ert="x"), "ert"), (dict(dt=[1, 2]), "dt")])
def test_non_numeric_dt_ert(small, kw, name):
    vol, tf, cam = small
    with pytest.raises(ParameterError, match=name):
        sc.render(vol, tf, cam, 8, 8, **kw)


