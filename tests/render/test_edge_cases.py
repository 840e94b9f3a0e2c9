"""Inputs that must still give a correct image: empty volumes, invisible TFs, thin volumes, cameras inside.
"""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast import Camera, TransferFunction, Volume, render
from sparsecast.errors import VolumeDataError
from render_helpers import assert_matches_reference, random_volume


# ---------------------------------------------------------------------------------
# edge cases that must still give a correct image
# ---------------------------------------------------------------------------------
def test_all_zero_volume_is_transparent():
    vol = Volume(np.zeros((6, 7, 8), np.float32), spacing=(1.0, 0.5, 2.0))
    tf = TransferFunction.preset("viridis", (0.0, 1.0))
    for cam in (Camera.orbit(vol, 30, 40), Camera.orbit(vol, 0, 90, projection="orthographic")):
        img, _ = assert_matches_reference(vol, tf, cam, 10, 9)
        assert np.all(img.rgba == 0.0)
        assert img.stats["samples_nonempty"] == 0


@pytest.mark.parametrize("background", [(0.2, 0.3, 0.4, 1.0), (0.2, 0.3, 0.4, 0.5), "white", "transparent"])
def test_tf_without_opacity_gives_background(rng, background):
    vol = random_volume(rng, (6, 7, 8), "float32")
    tf = TransferFunction([(0.0, 1.0, 0.0, 0.0, 0.0), (0.5, 0.0, 1.0, 0.0, 0.0), (1.0, 0.0, 0.0, 1.0, 0.0)])
    assert tf.is_transparent
    assert tf.is_empty(-1e9, 1e9)
    img = sc.render(vol, tf, Camera.orbit(vol, 15, 25), 11, 7, background=background)
    if isinstance(background, str):
        background = {"white": (1.0, 1.0, 1.0, 1.0), "transparent": (0.0, 0.0, 0.0, 0.0)}[background]
    bg = np.asarray(background, np.float64)
    expected = np.append(bg[:3] * bg[3], bg[3]).astype(np.float32)  # premultiplied
    assert np.all(img.rgba == expected)
    assert img.stats["samples_nonempty"] == 0


@pytest.mark.parametrize("shape", [(1, 8, 8), (8, 1, 8), (8, 8, 1), (1, 1, 5), (1, 1, 1)])
def test_one_voxel_thick_volume_is_refused(rng, shape):
    # It would render empty from every view (a box of zero thickness): refused by name
    # instead (issue 14, item 12; see tests/render/test_thin_volume.py).
    vol = random_volume(rng, shape, "float32", density=1.0, spacing=(1.0, 1.5, 0.5), origin=(1.0, -2.0, 0.5))
    tf = TransferFunction.preset("grayscale", (0.0, 1.0))
    with pytest.raises(VolumeDataError, match="at least 2 voxels per axis"):
        render(vol, tf, Camera.orbit(vol), 9, 7)


def test_camera_inside_volume(rng):
    vol = random_volume(rng, (10, 12, 9), "float32", spacing=(1.0, 0.8, 1.2), origin=(5.0, 0.0, -5.0))
    tf = TransferFunction.preset("inferno", (0.0, 1.0), threshold=0.3)
    c = vol.center
    for target in ([1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.3, 0.5, -0.4]):
        up = (0, 1, 0) if target == [0.0, 0.0, 1.0] else (0, 0, 1)
        for proj in ("perspective", "orthographic"):
            cam = Camera.look_at(c, c + np.array(target), up, projection=proj, fov_y=90.0, ortho_height=6.0)
            img, _ = assert_matches_reference(vol, tf, cam, 12, 10, dt=0.4)
            assert np.all(img.samples > 0)  # every ray starts inside the box


