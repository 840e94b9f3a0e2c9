"""The driver's clip box (half-open faces), clip caps, initial RGBA and screen rectangle.

Each is exact: every index equals naive under the same clip; pieces that share a
face, rendered one after the other with ``initial``, equal the whole volume with
sample counts adding up exactly (no sample on the shared face twice, none lost);
a rectangle equals the same pixels of the full image, bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast import ParameterError
from synthetic import label_volume, sparse_volume

from sparsecast.index.registry import _INDICES

# Last index first. pytest-xdist starts its two workers on the two files with the
# most tests, this one and tests/index/test_exactness.py, which compiles the indices
# in registry order: walking them the other way (and starting with the label test
# below, which that file reaches late) the workers compile different kernels, and
# each finds the other's in the disk cache, instead of compiling the same ones side
# by side (measured: a cold run 1128 -> 1070 s, two workers).
EXACT = [n for n in reversed(sc.available_indices()) if _INDICES[n].exact]
ATOL = 1e-5


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(4)
    vol = sparse_volume(rng, (30, 26, 34), 12)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    return vol, tf


def _axis_camera(vol, dt):
    """Orthographic along +x from an eye whose x makes lattice samples land on integer x."""
    c = vol.center
    eye = np.array([-10.0, c[1] + 0.37, c[2] - 0.21])
    return sc.Camera.look_at(eye, eye + [1.0, 0.0, 0.0], up=(0, 0, 1), projection="orthographic",
                             ortho_height=vol.diagonal * 0.8)


@pytest.mark.parametrize("name", ["kdtree-deep", "grid-pc", "lbvh"])
@pytest.mark.parametrize("smooth", [False, True])
def test_clip_caps_on_labels_equal_naive(name, smooth):
    vol = label_volume(np.random.default_rng(8), (26, 30, 22), 5, brick_aligned=True)
    tf = sc.TransferFunction.labels({1: (1, 0, 0, 1), 3: (0, 1, 0, 0.5), 5: (0, 0, 1, 0.8)}, smooth=smooth)
    cam = sc.Camera.orbit(vol, 50, -20)
    kw = dict(dt=0.5, ert=1.0, clip_cap=True, clip_planes=[((11.0, 13.0, 12.0), (-1.0, 0.2, 0.5))])
    ref = sc.render(vol, tf, cam, 24, 24, index="naive", **kw)
    img = sc.render(vol, tf, cam, 24, 24, index=name, **kw)
    assert np.abs(img.rgba - ref.rgba).max() <= ATOL
    assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"]


@pytest.mark.parametrize("name", EXACT)
@pytest.mark.parametrize("shade", [False, True])
def test_clip_box_equals_naive(scene, name, shade):
    vol, tf = scene
    box = ((4.0, 3.5, 2.0), (27.25, 20.0, 25.0))
    opened = ((True, False, False), (False, True, True))
    cam = sc.Camera.orbit(vol, 40, 25)
    kw = dict(dt=0.5, clip_box=box, clip_open=opened, shading=shade, ert=1.0)
    ref = sc.render(vol, tf, cam, 28, 24, index="naive", **kw)
    img = sc.render(vol, tf, cam, 28, 24, index=name, **kw)
    assert np.abs(img.rgba - ref.rgba).max() <= ATOL
    assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"]
    full = sc.render(vol, tf, cam, 28, 24, index="naive", dt=0.5, shading=shade, ert=1.0)
    assert ref.stats["samples"] < full.stats["samples"]  # the clip removes samples


@pytest.mark.parametrize("name", ["naive", "kdtree-deep", "lbvh", "grid-pc"])
@pytest.mark.parametrize("shade", [False, True])
def test_pieces_sharing_a_face_equal_the_whole(scene, name, shade):
    vol, tf = scene
    dt = 0.5
    cam = _axis_camera(vol, dt)
    cut = 15.0  # samples land exactly on x = 15 (eye at x = -10, dt = 0.5)
    lo, hi = vol.bounds
    front = ((lo[0], lo[1], lo[2]), (cut, hi[1], hi[2]))
    back = ((cut, lo[1], lo[2]), (hi[0], hi[1], hi[2]))
    kw = dict(dt=dt, index=name, shading=shade, ert=1.0)
    whole = sc.render(vol, tf, cam, 30, 26, **kw)
    a = sc.render(vol, tf, cam, 30, 26, clip_box=front, clip_open=((False,) * 3, (True, False, False)), **kw)
    b = sc.render(vol, tf, cam, 30, 26, clip_box=back, initial=a.rgba, **kw)
    assert np.abs(b.rgba - whole.rgba).max() <= ATOL
    assert np.array_equal(a.samples + b.samples, whole.samples)
    # Both faces closed: the samples on x = 15 are taken twice.
    a2 = sc.render(vol, tf, cam, 30, 26, clip_box=front, **kw)
    assert (a2.samples + b.samples).sum() > whole.samples.sum()


@pytest.mark.parametrize("name", EXACT)
def test_rect_is_a_crop_of_the_full_image(scene, name):
    vol, tf = scene
    cam = sc.Camera.orbit(vol, -60, 15)
    full = sc.render(vol, tf, cam, 37, 29, index=name, shading=True)
    part = sc.render(vol, tf, cam, 37, 29, index=name, shading=True, rect=(5, 3, 20, 17))
    assert part.rgba.shape == (17, 20, 4)
    assert np.array_equal(part.rgba, full.rgba[3:20, 5:25])
    assert np.array_equal(part.samples, full.samples[3:20, 5:25])


def test_initial_opacity_at_ert_takes_no_samples(scene):
    vol, tf = scene
    cam = sc.Camera.orbit(vol, 10, 10)
    init = np.zeros((12, 12, 4), np.float32)
    init[..., :] = (0.5, 0.2, 0.1, 0.995)
    img = sc.render(vol, tf, cam, 12, 12, initial=init, background="white")
    assert img.stats["samples"] == 0
    expected = init + (1.0 - init[..., 3:4]) * np.array([1, 1, 1, 1], np.float32)
    assert np.allclose(img.rgba, expected, atol=1e-6)


PLANES = [((10.0, 10.0, 12.0), (1.0, 0.3, -0.2)), ((0.0, 18.0, 0.0), (0.0, -1.0, 0.4))]


@pytest.mark.parametrize("name", EXACT)
def test_clip_planes_equal_naive(scene, name):
    vol, tf = scene
    cam = sc.Camera.orbit(vol, -35, 30)
    kw = dict(dt=0.5, clip_planes=PLANES, ert=1.0, shading=True)
    ref = sc.render(vol, tf, cam, 26, 22, index="naive", **kw)
    img = sc.render(vol, tf, cam, 26, 22, index=name, **kw)
    assert np.abs(img.rgba - ref.rgba).max() <= ATOL
    assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"]
    assert img.stats["samples"] <= ref.stats["samples"]


def test_clip_plane_is_a_half_box(scene):
    """An axis-aligned plane keeps what the same clip box face keeps."""
    vol, tf = scene
    lo, hi = vol.bounds
    cut = 12.3
    cam = sc.Camera.orbit(vol, 25, 15)
    whole = sc.render(vol, tf, cam, 30, 24, dt=0.5, index="naive")
    plane = sc.render(vol, tf, cam, 30, 24, dt=0.5, index="naive", clip_planes=[((cut, 0, 0), (2.0, 0, 0))])
    box = sc.render(vol, tf, cam, 30, 24, dt=0.5, index="naive", clip_box=((cut, lo[1], lo[2]), tuple(hi)))
    assert np.abs(plane.rgba - box.rgba).max() <= ATOL
    assert abs(plane.stats["samples"] - box.stats["samples"]) <= 2  # rounding at the plane itself
    assert plane.stats["samples"] < whole.stats["samples"]


# -- clip caps: the first sample behind a cut face lit with the face's normal ------------
CLIPS = {
    "box": dict(clip_box=((4.0, 3.5, 2.0), (27.25, 20.0, 25.0))),
    "planes": dict(clip_planes=PLANES),
    "box+plane": dict(clip_box=((0.0, 6.0, 0.0), (40.0, 40.0, 17.5)), clip_planes=PLANES[:1]),
}


@pytest.mark.parametrize("name", EXACT)
@pytest.mark.parametrize("clip", sorted(CLIPS))
@pytest.mark.parametrize("shade", [False, True])
def test_clip_caps_equal_naive(scene, name, clip, shade):
    vol, tf = scene
    cam = sc.Camera.orbit(vol, 120, 20)  # from the side the planes remove: their cut faces are in view
    kw = dict(dt=0.5, ert=1.0, shading=shade, clip_cap=True, **CLIPS[clip])
    ref = sc.render(vol, tf, cam, 26, 22, index="naive", **kw)
    img = sc.render(vol, tf, cam, 26, 22, index=name, **kw)
    assert np.abs(img.rgba - ref.rgba).max() <= ATOL
    assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"]
    assert img.stats["samples"] <= ref.stats["samples"]
    uncapped = sc.render(vol, tf, cam, 26, 22, index=name, **{**kw, "clip_cap": False})
    assert np.abs(img.rgba - uncapped.rgba).max() > 0.01  # the caps show


def _solid():
    """A uniform opaque block (TF colour (0.5, 0.2, 0.1) at opacity 1) seen along -z."""
    vol = sc.Volume(np.ones((20, 20, 20), np.float32))
    tf = sc.TransferFunction([(0.0, 0.5, 0.2, 0.1, 0.0), (1.0, 0.5, 0.2, 0.1, 1.0)])
    c = vol.center
    cam = sc.Camera.look_at(c + [0, 0, 50], c, up=(0, 1, 0), projection="orthographic", ortho_height=16)
    return vol, tf, cam


def _lit(colour, ndl):
    """Blinn-Phong with DEFAULT_SHADING at |n . l| = ndl (headlight)."""
    ka, kd, ks, shininess = 0.3, 0.7, 0.25, 24.0
    return np.minimum(np.asarray(colour) * (ka + kd * ndl) + ks * ndl ** shininess, 1.0)


@pytest.mark.parametrize("shade", [False, True])
def test_cap_lights_a_clip_plane_with_its_normal(shade):
    """A plane through the block, tilted 53 degrees from the view: where rays enter through
    it, the pixel is the cap (|n . l| = 0.6); where they enter through the volume's top
    face (y > 12.5), the block's own colour (uniform: zero gradient, ka + kd = 1 if shaded)."""
    vol, tf, cam = _solid()
    plane = [((9.5, 9.5, 15.0), (0.0, 0.8, -0.6))]
    img = sc.render(vol, tf, cam, 32, 32, index="naive", shading=shade, clip_planes=plane, clip_cap=True).rgba
    rgb = img[..., :3].reshape(-1, 3)
    cap = np.all(np.abs(rgb - _lit((0.5, 0.2, 0.1), 0.6)) < 1e-5, axis=1)
    own = np.all(np.abs(rgb - (0.5, 0.2, 0.1)) < 1e-5, axis=1)
    assert cap.sum() > 200 and own.sum() > 200 and (cap | own).all()
    plain = sc.render(vol, tf, cam, 32, 32, index="naive", shading=shade, clip_planes=plane).rgba
    assert np.all(np.abs(plain[..., :3].reshape(-1, 3) - (0.5, 0.2, 0.1)) < 1e-5)


def test_cap_lights_clip_box_faces_inside_the_volume_only():
    """The box's top face cuts the block (a cap, |n . l| = 1); a box face on the volume's
    own face is no cut (no cap there)."""
    vol, tf, cam = _solid()
    lo, hi = vol.bounds
    cut = sc.render(vol, tf, cam, 24, 24, index="naive", clip_cap=True,
                    clip_box=(tuple(lo), (hi[0], hi[1], 12.3))).rgba
    np.testing.assert_allclose(cut[..., :3], np.broadcast_to(_lit((0.5, 0.2, 0.1), 1.0), cut[..., :3].shape),
                               atol=1e-5)
    same = sc.render(vol, tf, cam, 24, 24, index="naive", clip_cap=True, clip_box=(tuple(lo), tuple(hi))).rgba
    np.testing.assert_allclose(same[..., :3], np.broadcast_to((0.5, 0.2, 0.1), same[..., :3].shape), atol=1e-5)


@pytest.mark.parametrize("kw, match", [
    (dict(clip_cap="yes"), "clip_cap: expected True or False"),
    (dict(clip_cap=True, mode="iso", iso=0.5), "clip_cap: .*expected mode='dvr'"),

    (dict(clip_planes=[((0, 0, 0), (0, 0, 0))]), "normal"),
    (dict(clip_planes=[((0, 0, 0), (1, 0, 0))] * 7), "clip_planes"),
    (dict(clip_planes=[((0, 0, float("nan")), (1, 0, 0))]), "clip_planes"),
    (dict(clip_planes=[(1, 2, 3)]), "clip_planes"),
    (dict(rect=(0, 0, 0, 4)), "rect"),
    (dict(rect=(10, 0, 8, 4)), "rect"),
    (dict(rect=(0, 0, 4)), "rect"),
    (dict(clip_box=((0, 0, 0), (1, 1))), "clip_box"),
    (dict(clip_box=((5, 0, 0), (1, 1, 1))), "clip_box"),
    (dict(clip_box=((0, 0, 0), (1, 1, float("nan")))), "clip_box"),
    (dict(clip_open=((True,) * 3, (True,) * 3)), "clip_open"),
    (dict(clip_box=((0, 0, 0), (9, 9, 9)), clip_open=((1, 0, 0), (0, 0, 0))), "clip_open"),
    (dict(initial=np.zeros((3, 3, 4))), "initial"),
    (dict(initial=np.full((12, 12, 4), np.nan)), "initial"),
])
def test_bad_options(scene, kw, match):
    vol, tf = scene
    with pytest.raises(ParameterError, match=match):
        sc.render(vol, tf, sc.Camera.orbit(vol), 12, 12, **kw)
