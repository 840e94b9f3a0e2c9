"""`--view`, `--up` and `--orientation` on render, info and view: the command renders what
the API does with the same frame, and an oriented volume is seen from the front by default."""

from __future__ import annotations

import nrrd
import numpy as np
import pytest

import sparsecast as sc
from cli_runner import run_cli


@pytest.fixture(scope="module")
def lps_file(tmp_path_factory):
    """A 20x16x12 NRRD in ``space: left-posterior-superior`` with an asymmetric blob."""
    rng = np.random.default_rng(5)
    a = (rng.random((12, 16, 20)) * 40).astype(np.uint8)
    a[3:7, 2:6, 4:9] = 220  # near the anterior (+j is posterior) face, off centre
    path = tmp_path_factory.mktemp("views") / "head.nrrd"
    nrrd.write(str(path), a, {"space": "left-posterior-superior", "space directions": np.diag([1.0, 1.5, 2.0]),
                              "space origin": np.zeros(3)}, index_order="C")
    return path


@pytest.fixture(scope="module")
def plain_file(tmp_path_factory):
    a = (np.random.default_rng(6).random((10, 12, 14)) * 255).astype(np.uint8)
    path = tmp_path_factory.mktemp("views") / "plain.nrrd"
    nrrd.write(str(path), a, {"space dimension": 3, "space directions": np.eye(3)}, index_order="C")
    return path


def _render(monkeypatch, capsys, tmp_path, *args):
    arr = tmp_path / "img.npy"
    code, stdout, err = run_cli(monkeypatch, capsys, "render", *args, "--tf", "bone", "--size", "32x24",
                                "--index", "naive", "--dt", "0.5", "--background", "transparent", "-o", str(tmp_path / "img.png"), "--array", str(arr))
    return code, stdout, err, (np.load(arr) if code == 0 else None)


def _api(path, *angles, orientation=None, **frame):
    vol = sc.load_volume(path, orientation=orientation)
    tf = sc.TransferFunction.preset("bone", vol.value_range)
    return sc.render(vol, tf, sc.Camera.orbit(vol, *angles, **frame), 32, 24, dt=0.5, index="naive").rgba


def test_oriented_volume_defaults_to_the_anterior_view(monkeypatch, capsys, tmp_path, lps_file):
    code, stdout, err, img = _render(monkeypatch, capsys, tmp_path, str(lps_file))
    assert code == 0, err
    assert "view anterior (LPS)" in stdout
    np.testing.assert_array_equal(img, _api(lps_file, 0, 0, view="anterior"))
    assert not np.array_equal(img, _api(lps_file, 30, 20))  # not the old z-up three-quarter view


@pytest.mark.parametrize("args, angles, frame", [
    (["--view", "left"], (0, 0), {"view": "left"}),
    (["--view", "superior", "--azimuth", "15", "--elevation", "-10"], (15, -10), {"view": "superior"}),
    (["--up", "-y"], (30, 20), {"up": "-y"}),
])
def test_view_and_up_match_the_api(monkeypatch, capsys, tmp_path, lps_file, args, angles, frame):
    code, _, err, img = _render(monkeypatch, capsys, tmp_path, str(lps_file), *args)
    assert code == 0, err
    np.testing.assert_array_equal(img, _api(lps_file, *angles, **frame))


def test_view_needs_an_orientation(monkeypatch, capsys, tmp_path, plain_file):
    code, stdout, err, _ = _render(monkeypatch, capsys, tmp_path, str(plain_file), "--view", "anterior")
    assert code == 2 and err.startswith("error: --view anterior: ") and len(err.strip().splitlines()) == 1
    assert str(plain_file) in err and "no anatomical orientation" in err and "--orientation" in err
    assert not (tmp_path / "img.png").exists()
    # Without a view it orbits about z as before; --orientation supplies the codes.
    code, stdout, err, img = _render(monkeypatch, capsys, tmp_path, str(plain_file))
    assert code == 0 and ", view " not in stdout
    np.testing.assert_array_equal(img, _api(plain_file, 30, 20))
    code, stdout, err, img = _render(monkeypatch, capsys, tmp_path, str(plain_file), "--orientation", "RAS",
                                     "--view", "posterior")
    assert code == 0, err
    np.testing.assert_array_equal(img, _api(plain_file, 0, 0, orientation="RAS", view="posterior"))


@pytest.mark.parametrize("args, needle", [
    (["--up", "y", "--view", "left"], "give one of them"),
    (["--view", "front"], "--view: expected one of anterior"),
    (["--up", "up"], "--up: expected one of x, y, z"),
    (["--orientation", "RAX"], "--orientation: expected three axis codes"),
])
def test_bad_frame_options_are_one_line(monkeypatch, capsys, tmp_path, lps_file, args, needle):
    code, _, err, _ = _render(monkeypatch, capsys, tmp_path, str(lps_file), *args)
    assert code == 2 and needle in err and len(err.strip().splitlines()) == 1


def test_info_prints_the_orientation(monkeypatch, capsys, lps_file, plain_file):
    code, stdout, err = run_cli(monkeypatch, capsys, "info", str(lps_file))
    assert code == 0, err
    assert "anatomy   LPS (+i left, +j posterior, +k superior)" in stdout
    code, stdout, _ = run_cli(monkeypatch, capsys, "info", str(plain_file))
    assert code == 0 and "no orientation in the file" in stdout


def test_viewer_orbits_in_the_view_frame(lps_file, plain_file):
    pytest.importorskip("starlette")
    from sparsecast.errors import ParameterError
    from sparsecast.viewer.messages import CameraSpec
    from sparsecast.viewer.session import Session, ViewerData

    vol = sc.load_volume(lps_file)
    data = ViewerData.create(vol, "bone", camera=CameraSpec(10.0, 5.0), view="anterior")
    cam = Session(data)._camera(data.camera)
    ref = sc.Camera.orbit(vol, 10.0, 5.0, view="anterior")
    np.testing.assert_allclose(cam.eye, ref.eye)
    np.testing.assert_allclose(cam.up, ref.up)
    with pytest.raises(ParameterError, match="no anatomical orientation"):
        ViewerData.create(sc.load_volume(plain_file), "bone", view="left")


def test_view_command_refuses_a_view_without_orientation(monkeypatch, capsys, plain_file):
    pytest.importorskip("starlette")
    code, _, err = run_cli(monkeypatch, capsys, "view", str(plain_file), "--view", "left", "--no-browser", "--port", "0")
    assert code == 2 and str(plain_file) in err and "--orientation" in err
