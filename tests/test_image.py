"""``Image.save``: formats, straight alpha for PNG, atomic writes.
"""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast import ParameterError





# ---------------------------------------------------------------------------------
# Image.save
# ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def opaque_image(small):
    vol, tf, cam = small
    img = sc.render(vol, tf, cam, 20, 14, background="black")
    assert np.all(img.rgba[..., 3] == 1.0)
    return img


def test_save_png_round_trip(tmp_path, opaque_image):
    from PIL import Image as PILImage

    p = opaque_image.save(tmp_path / "out.png")
    assert p == tmp_path / "out.png"
    with PILImage.open(p) as im:
        assert im.mode == "RGBA"
        arr = np.asarray(im)
    assert arr.shape == (14, 20, 4)
    expected = np.rint(255.0 * opaque_image.rgba[..., :3].astype(np.float64))
    np.testing.assert_array_equal(arr[..., :3], expected.astype(np.uint8))
    assert np.all(arr[..., 3] == 255)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["out.png"]


def test_save_png_straight_alpha(tmp_path, small):
    vol, tf, cam = small
    img = sc.render(vol, tf, cam, 20, 14)
    from PIL import Image as PILImage

    with PILImage.open(img.save(tmp_path / "a.png")) as im:
        arr = np.asarray(im).astype(np.float64)
    a = img.rgba[..., 3].astype(np.float64)
    np.testing.assert_array_equal(arr[..., 3], np.rint(255 * a))
    vis = a > 0.2
    straight = img.rgba[..., :3][vis] / a[vis][:, None]
    assert np.abs(arr[..., :3][vis] - 255 * straight).max() <= 0.5 + 1e-3


def test_save_npy_round_trip(tmp_path, opaque_image):
    p = opaque_image.save(tmp_path / "out.npy")
    back = np.load(p)
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, opaque_image.rgba)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["out.npy"]


def test_save_unknown_suffix(tmp_path, opaque_image):
    with pytest.raises(ParameterError, match=r"\.xyz"):
        opaque_image.save(tmp_path / "out.xyz")
    assert list(tmp_path.iterdir()) == []


def test_save_missing_directory(tmp_path, opaque_image):
    with pytest.raises(ParameterError, match="directory"):
        opaque_image.save(tmp_path / "nope" / "out.png")


def test_failed_save_leaves_nothing(tmp_path, opaque_image, monkeypatch):
    from PIL import Image as PILImage

    def boom(self, *args, **kwargs):
        # write something first, as a real encoder would before failing
        target = args[0] if args else kwargs.get("fp")
        with open(target, "wb") as fh:
            fh.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(PILImage.Image, "save", boom)
    with pytest.raises(sc.FileFormatError, match="cannot write: disk full"):
        opaque_image.save(tmp_path / "out.png")
    assert list(tmp_path.iterdir()) == []

    existing = tmp_path / "keep.png"
    existing.write_bytes(b"old content")
    with pytest.raises(sc.FileFormatError, match="cannot write: disk full"):
        opaque_image.save(existing)
    assert existing.read_bytes() == b"old content"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["keep.png"]


