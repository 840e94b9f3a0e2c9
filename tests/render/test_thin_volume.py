"""A one-voxel-thick volume (issue 14, item 12) is refused with a clear error, never a
silently empty image."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.errors import VolumeDataError


@pytest.mark.parametrize("shape, axis", [((1, 64, 64), "z"), ((8, 1, 8), "y"), ((8, 8, 1), "x")])
def test_single_voxel_axis_is_refused(shape, axis):
    vol = sc.Volume(np.ones(shape, np.float32))
    tf = sc.TransferFunction([(0, 1, 1, 1, 1), (1, 1, 1, 1, 1)])
    cam = sc.Camera.orbit(sc.Volume(np.ones((4, 4, 4), np.float32)))
    with pytest.raises(VolumeDataError, match=rf"{shape}.*single voxel along {axis}.*at least 2 voxels per axis"):
        sc.render(vol, tf, cam, 8, 8)
