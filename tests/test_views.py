"""Anatomical orientation survives loading (NRRD ``space``, NIfTI sform/qform), and named
views look at the patient from the side they name: checked on the camera's geometry in
world coordinates and by which of two markers occludes the other."""

from __future__ import annotations

import nibabel as nib
import nrrd
import numpy as np
import pytest

import sparsecast as sc
from sparsecast.axes import VIEWS, anatomical_direction, check_orientation, view_frame
from sparsecast.errors import ParameterError

SHAPE = (14, 20, 16)  # (nz, ny, nx): no two axes alike


def marked(orientation) -> np.ndarray:
    """Zeros with two cubes on the anterior-posterior line through the centre: value 100
    near the anterior face, 200 near the posterior face (for voxel axes ``orientation``)."""
    a = np.zeros(SHAPE, np.uint8)
    c = [n // 2 for n in SHAPE[::-1]]  # (i, j, k) of the centre
    axis = next(n for n, code in enumerate(orientation) if code in "AP")
    n = SHAPE[::-1][axis]
    for value, toward in ((100, "A"), (200, "P")):
        at = 2 if (orientation[axis] == toward) == False else n - 3  # noqa: E712 - the far end of +axis is `toward`
        lo = list(c)
        lo[axis] = at
        sl = tuple(slice(lo[d] - 1, lo[d] + 2) for d in (2, 1, 0))  # [k, j, i]
        a[sl] = value
    return a


def two_colour_tf() -> sc.TransferFunction:
    """100 -> red (alpha 0.3 per sample: a 3-voxel cube is opaque), 200 -> opaque green, 0
    transparent. The trilinear ramp from 0 up to a green cube crosses the red band in a
    tenth of a voxel, so that film adds at most one faint red sample."""
    pts = [(0, 0, 0, 0, 0), (85, 1, 0, 0, 0), (90, 1, 0, 0, 0.3), (110, 1, 0, 0, 0.3), (115, 0, 0, 0, 0),
           (175, 0, 1, 0, 0), (180, 0, 1, 0, 1), (255, 0, 1, 0, 1)]
    return sc.TransferFunction(pts, (0, 255), table_size=4096)


def write_nrrd_lps(path, data: np.ndarray, flip_i: bool = False) -> None:
    """``space: left-posterior-superior``; with ``flip_i`` the first axis points right."""
    dirs = np.diag([-1.5 if flip_i else 1.5, 2.0, 1.0])
    nrrd.write(str(path), data, {"space": "left-posterior-superior", "space directions": dirs,
                                 "space origin": np.zeros(3), "kinds": ["domain"] * 3}, index_order="C")


def write_nifti(path, data: np.ndarray, affine: np.ndarray) -> None:
    img = nib.Nifti1Image(data.transpose(2, 1, 0), affine)  # (z, y, x) -> (x, y, z)
    img.header.set_qform(affine, code=1)
    img.header.set_sform(affine, code=1)
    nib.save(img, str(path))


# NIfTI (RAS+ world): +i -> posterior (-y), +j -> superior (+z), +k -> left (-x): codes P, S, L
NIFTI_AFFINE = np.array([[0, 0, -1.2, 10], [-2.0, 0, 0, 20], [0, 1.5, 0, -5], [0, 0, 0, 1]])


@pytest.fixture(params=["nrrd", "nrrd-flipped", "nifti"])
def oriented(request, tmp_path):
    """(path, expected axis codes) of a marked volume in each format."""
    if request.param == "nifti":
        codes = ("P", "S", "L")
        path = tmp_path / "m.nii.gz"
        write_nifti(path, marked(codes), NIFTI_AFFINE)
    else:
        flip = request.param == "nrrd-flipped"
        codes = ("R" if flip else "L", "P", "S")
        path = tmp_path / "m.nrrd"
        write_nrrd_lps(path, marked(codes), flip)
    return path, codes


def test_orientation_is_kept_by_the_readers(oriented):
    path, codes = oriented
    vol = sc.load_volume(path)
    assert vol.orientation == codes
    assert sc.load_volume(path, orientation="ras").orientation == ("R", "A", "S")  # an override wins


@pytest.mark.parametrize("view", list(VIEWS))
def test_named_view_geometry_in_world_coordinates(oriented, view):
    """The camera sits on the named side of the centre, superior (anterior from above or below)
    up, and the patient's left is on screen right seen from the front (radiological)."""
    path, codes = oriented
    vol = sc.load_volume(path)
    cam = sc.Camera.orbit(vol, view=view, projection="orthographic")
    side, top = VIEWS[view]
    to_eye = (cam.eye - vol.center) / np.linalg.norm(cam.eye - vol.center)
    np.testing.assert_allclose(to_eye, anatomical_direction(codes, side), atol=1e-12)
    forward, right, up = cam.basis()
    np.testing.assert_allclose(up, anatomical_direction(codes, top), atol=1e-12)
    if view == "anterior":
        np.testing.assert_allclose(right, anatomical_direction(codes, "L"), atol=1e-12)
    if view == "posterior":
        np.testing.assert_allclose(right, anatomical_direction(codes, "R"), atol=1e-12)


def _centroid(rgba: np.ndarray, channel: int) -> np.ndarray:
    m = rgba[..., channel] > 0.5
    assert m.any(), f"channel {channel} not visible"
    rows, cols = np.nonzero(m)
    return np.array([rows.mean(), cols.mean()])


def test_anterior_marker_is_in_front_from_the_front(oriented):
    path, _ = oriented
    vol = sc.load_volume(path)
    tf = two_colour_tf()
    centre = {}
    for view in ("anterior", "posterior"):
        cam = sc.Camera.orbit(vol, view=view, projection="orthographic")
        rgba = sc.render(vol, tf, cam, 48, 48, dt=0.25, index="naive").rgba
        centre[view] = rgba[24, 24, :3]
    assert centre["anterior"][0] > 0.5 > centre["anterior"][1]  # red: the anterior marker occludes
    assert centre["posterior"][1] > 0.5 > centre["posterior"][0]  # green from behind
    imgs = {v: sc.render(vol, tf, sc.Camera.orbit(vol, view=v, projection="orthographic"), 48, 48,
                         dt=0.25, index="naive").rgba for v in ("left", "right", "superior", "inferior")}
    # Side views: the face (anterior, red) is on the screen's left seen from the left, right from the right.
    assert _centroid(imgs["left"], 0)[1] < _centroid(imgs["left"], 1)[1]
    assert _centroid(imgs["right"], 0)[1] > _centroid(imgs["right"], 1)[1]
    # From above and below, anterior is up.
    for v in ("superior", "inferior"):
        assert _centroid(imgs[v], 0)[0] < _centroid(imgs[v], 1)[0]


def test_orbit_angles_turn_away_from_the_view(oriented):
    path, codes = oriented
    vol = sc.load_volume(path)
    a = sc.Camera.orbit(vol, 90, 0, view="anterior")
    b = sc.Camera.orbit(vol, 0, 0, view="right")  # azimuth turns counter-clockwise seen from above (superior)
    np.testing.assert_allclose(a.eye, b.eye, atol=1e-9)
    up90 = sc.Camera.orbit(vol, 0, 90, view="anterior")
    np.testing.assert_allclose((up90.eye - vol.center) / np.linalg.norm(up90.eye - vol.center),
                               anatomical_direction(codes, "S"), atol=1e-12)


def test_view_without_orientation_and_bad_names_are_clear_errors():
    vol = sc.Volume(np.zeros((4, 4, 4), np.uint8), name="plain")
    assert vol.orientation is None
    with pytest.raises(ParameterError, match=r"'plain' has no anatomical orientation.*orientation="):
        sc.Camera.orbit(vol, view="anterior")
    with pytest.raises(ParameterError, match="view: expected one of anterior"):
        view_frame(("R", "A", "S"), "front")
    with pytest.raises(ParameterError, match="give up or view"):
        sc.Camera.orbit(sc.Volume(np.zeros((4, 4, 4)), orientation="RAS"), up="y", view="left")
    for bad in ("RAX", "RRS", "RA", ("R", "A", "S", "I")):
        with pytest.raises(ParameterError, match="orientation: expected three axis codes"):
            check_orientation(bad)


@pytest.mark.parametrize("up", ["x", "y", "-y", "-z"])
def test_up_rotates_the_camera_not_the_data(up):
    """Orbiting a volume about world axis `up` is the z-up orbit of the volume turned so that
    `up` is +z: the same camera up to the rotation (so the render is exact for every index)."""
    from sparsecast.axes import axis_vector, up_frame

    vol = sc.Volume(np.zeros((6, 8, 10), np.float32), spacing=(1, 2, 3), origin=(1, -2, 5))
    cam = sc.Camera.orbit(vol, 30, 20, up=up)
    ref = sc.Camera.orbit(vol, 30, 20)  # z up
    m = up_frame(up)
    np.testing.assert_allclose(cam.eye - vol.center, m @ (ref.eye - vol.center), atol=1e-9)
    np.testing.assert_allclose(cam.basis()[2], m @ ref.basis()[2], atol=1e-12)
    assert np.dot(sc.Camera.orbit(vol, 0, 0, up=up).basis()[2], axis_vector(up)) == pytest.approx(1.0)


def test_save_volume_keeps_the_orientation(oriented, tmp_path):
    path, codes = oriented
    vol = sc.load_volume(path)
    for suffix in (".nrrd", ".nii.gz"):
        out = sc.save_volume(vol, tmp_path / f"copy{suffix}")
        back = sc.load_volume(out)
        assert back.orientation == codes, suffix
        np.testing.assert_array_equal(back.data, vol.data)
        np.testing.assert_allclose(back.spacing, vol.spacing)
        np.testing.assert_allclose(back.origin, vol.origin)
    plain = sc.Volume(np.zeros((3, 3, 3), np.uint8))
    assert sc.load_volume(sc.save_volume(plain, tmp_path / "plain.nrrd")).orientation is None


MNI = "mni152_t1_197x233x189_uint8.nrrd"


def test_mni152_views(shared_data_dir):
    """The shared MNI152 file lost its orientation in conversion (no NRRD ``space``); the
    template is RAS, and its views then show the brain from the named sides: from the left,
    the cerebellum and brainstem (posterior, the lowest part) are right of centre, the face
    side left; the (symmetric) template seen from the right is the exact mirror image; from
    above it is longer (anterior-posterior) than wide."""
    path = shared_data_dir / MNI
    if not path.exists():
        pytest.skip(f"{path} absent")
    assert sc.load_volume(path).orientation is None
    vol = sc.load_volume(path, orientation="RAS")
    tf = sc.TransferFunction.preset("bone", vol.value_range)
    cam = sc.Camera.orbit(vol, view="anterior", projection="orthographic")
    assert (cam.eye - vol.center)[1] > 0 and cam.basis()[2][2] == pytest.approx(1.0)  # at +y (anterior), z up
    rgba = {v: sc.render(vol, tf, sc.Camera.orbit(vol, view=v, projection="orthographic"), 96, 96, dt=1.0).rgba
            for v in ("left", "right", "superior")}
    rows, cols = np.nonzero(rgba["left"][..., 3] > 0.5)
    bottom = rows > rows.max() - 0.2 * np.ptp(rows)
    assert cols[bottom].mean() - (cols.min() + cols.max()) / 2 > 0.08 * np.ptp(cols)
    diff = lambda a, b: float(np.abs(a - b).mean())  # noqa: E731
    assert diff(rgba["left"], rgba["right"][:, ::-1]) < 0.2 * diff(rgba["left"], rgba["right"])
    rows, cols = np.nonzero(rgba["superior"][..., 3] > 0.5)
    assert np.ptp(rows) > np.ptp(cols) * 1.1
