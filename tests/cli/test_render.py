"""`sparsecast render`: images that match the API, index options, outputs left complete or absent."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image as PILImage

import sparsecast as sc
from cli_runner import run_cli


def test_render_demo_default_writes_png_and_array(monkeypatch, capsys, tmp_path):
    out = tmp_path / "demo.png"
    arr = tmp_path / "demo.npy"
    code, stdout, err = run_cli(monkeypatch, capsys, "render", "--size", "40x30", "-o", str(out), "--array", str(arr))
    assert code == 0, err
    assert "wrote" in stdout
    with PILImage.open(out) as im:
        assert im.size == (40, 30)
        assert im.mode == "RGBA"
    rgba = np.load(arr)
    assert rgba.shape == (30, 40, 4) and rgba.dtype == np.float32
    # Black background: opaque everywhere, and the demo is visible somewhere.
    assert np.allclose(rgba[..., 3], 1.0)
    assert rgba[..., :3].max() > 0.05


def test_render_file_matches_api(monkeypatch, capsys, tmp_path, small_volume_file):
    arr = tmp_path / "img.npy"
    code, _, err = run_cli(
        monkeypatch, capsys, "render", str(small_volume_file), "--tf", "bone", "--size", "24x20",
        "--azimuth", "45", "--elevation", "-10", "--projection", "orthographic", "--dt", "0.7",
        "--background", "transparent", "-o", str(tmp_path / "img.png"), "--array", str(arr),
    )
    assert code == 0, err
    vol = sc.load_volume(small_volume_file)
    tf = sc.TransferFunction.preset("bone", vol.value_range)
    cam = sc.Camera.orbit(vol, 45, -10, projection="orthographic")
    ref = sc.render(vol, tf, cam, 24, 20, dt=0.7)
    np.testing.assert_allclose(np.load(arr), ref.rgba, atol=1e-6)


@pytest.mark.parametrize("spec, name, options", [
    ("bih:mode=single-sample", "bih", {"mode": "single-sample"}),
    ("grid-pc:cell=8", "grid-pc", {"cell": 8}),
])
def test_render_index_options_match_api(monkeypatch, capsys, tmp_path, small_volume_file, spec, name, options):
    arr = tmp_path / "img.npy"
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--size", "20x16",
                           "--index", spec, "-o", str(tmp_path / "img.png"), "--array", str(arr))
    assert code == 0, err
    vol = sc.load_volume(small_volume_file)
    tf = sc.TransferFunction.preset("viridis", vol.value_range)
    ref = sc.render(vol, tf, sc.Camera.orbit(vol, 30, 20), 20, 16, background="black", index=name, **options)
    np.testing.assert_allclose(np.load(arr), ref.rgba, atol=1e-6)


def test_output_directory_missing_leaves_nothing(monkeypatch, capsys, tmp_path):
    target = tmp_path / "missing" / "x.png"
    code, _, err = run_cli(monkeypatch, capsys, "render", "--size", "8x8", "-o", str(target))
    assert code == 2
    assert "missing" in err
    assert not target.parent.exists()


def test_unsupported_output_suffix_leaves_nothing(monkeypatch, capsys, tmp_path):
    code, _, err = run_cli(monkeypatch, capsys, "render", "--size", "8x8", "-o", str(tmp_path / "x.gif2"))
    assert code == 2 and "suffix" in err
    assert list(tmp_path.iterdir()) == []


def test_warning_for_transparent_tf(monkeypatch, capsys, tmp_path, small_volume_file):
    tf = sc.TransferFunction([(0, 1, 1, 1, 0), (1, 1, 1, 1, 0)])
    tf_path = tf.save(tmp_path / "clear.json")
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--tf", str(tf_path),
                           "--size", "8x8", "-o", str(tmp_path / "c.png"))
    assert code == 0
    assert "zero opacity" in err


@pytest.mark.parametrize("args, expected", [
    (["--index", "grid-pc:cel=8"], ["unknown option 'cel'", "grid-pc takes options: cell", "did you mean 'cell'"]),
    (["--cell", "7"], ["'auto'", "need a named index", "cell (--cell) applies to: grid-mm, grid-pc"]),
    (["--index", "naive", "--cell", "7"], ["'naive'", "unknown option 'cell'", "applies to: grid-mm, grid-pc"]),
    (["--index", "lbvh", "--cell", "8"], ["lbvh takes options: brick, prune, voting", "applies to: grid-mm"]),
    (["--index", "grid-pc:dt=0.5"], ["'dt' is a render parameter", "--dt"]),
    (["--index", "grid-mm:width=9"], ["'width' is a render parameter", "--size"]),
    (["--index", "naive:background=white"], ["--background"]),
])
def test_bad_index_options_are_one_line(monkeypatch, capsys, tmp_path, args, expected):
    out = tmp_path / "x.png"
    code, _, err = run_cli(monkeypatch, capsys, "render", "--size", "8x8", "-o", str(out), *args)
    assert code == 2, err
    assert "Traceback" not in err and "TypeError" not in err and "__init__" not in err
    flat = " ".join(err.split())  # rich wraps long lines
    for text in expected:
        assert text in flat, (text, err)
    assert not out.exists()


def test_info_indices_lists_options(monkeypatch, capsys):
    code, out, _ = run_cli(monkeypatch, capsys, "info", "--indices")
    assert code == 0
    lines = {line.split()[0]: line for line in out.splitlines()[1:] if line.strip()}
    assert "cell" in lines["grid-pc"] and "no options" in lines["naive"] and "prune" in lines["lbvh"]


def test_clip_box_and_planes_match_the_api(monkeypatch, capsys, tmp_path, small_volume_file):
    """``--clip-box`` and repeated ``--clip-plane`` reach render() unchanged (world units)."""
    vol = sc.load_volume(small_volume_file)
    lo, hi = vol.bounds
    mid = 0.5 * (lo + hi)
    box = (tuple(lo), (float(mid[0]), float(hi[1]), float(hi[2])))
    planes = [((0.0, float(mid[1]), 0.0), (0.0, 1.0, 0.0)), (tuple(mid), (0.0, 0.3, -1.0))]
    arr = tmp_path / "clip.npy"
    args = ["render", str(small_volume_file), "--size", "24x20", "--background", "transparent",
            "--clip-box", ",".join(f"{v:.17g}" for v in (*box[0], *box[1])), "-o", str(tmp_path / "c.png"),
            "--array", str(arr)]
    for p, n in planes:
        args += ["--clip-plane", ",".join(f"{v:.17g}" for v in (*p, *n))]
    code, _, err = run_cli(monkeypatch, capsys, *args)
    assert code == 0, err
    tf = sc.TransferFunction.preset("viridis", vol.value_range)
    cam = sc.Camera.orbit(vol, 30, 20)
    ref = sc.render(vol, tf, cam, 24, 20, background="transparent", clip_box=box, clip_planes=planes)
    full = sc.render(vol, tf, cam, 24, 20, background="transparent")
    np.testing.assert_allclose(np.load(arr), ref.rgba, atol=1e-6)
    assert ref.stats["samples_nonempty"] < full.stats["samples_nonempty"]


@pytest.mark.parametrize("opt, value", [("--clip-box", "0,0,0,1,1"), ("--clip-box", "5,0,0,1,1,1"),
                                        ("--clip-box", "0,0,0,1,inf,1"), ("--clip-plane", "0,0,0,1,0,x"),
                                        ("--clip-plane", "0,0,0,0,0,0")])
def test_bad_clip_options_are_one_error(monkeypatch, capsys, tmp_path, small_volume_file, opt, value):
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), opt, value,
                           "-o", str(tmp_path / "c.png"))
    assert code == 2
    assert err.count("error:") == 1 and opt in err and repr(value) in err  # the typed text, verbatim
    assert not (tmp_path / "c.png").exists()


def test_iso_mode_matches_the_api(monkeypatch, capsys, tmp_path, small_volume_file):
    vol = sc.load_volume(small_volume_file)
    lo, hi = vol.value_range
    values = [lo + 0.3 * (hi - lo), lo + 0.6 * (hi - lo)]
    arr = tmp_path / "iso.npy"
    code, out, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--size", "24x20",
                             "--mode", "iso+dvr", "--iso", repr(values[0]), "--iso", repr(values[1]),
                             "--background", "transparent", "-o", str(tmp_path / "iso.png"), "--array", str(arr))
    assert code == 0, err
    tf = sc.TransferFunction.preset("viridis", vol.value_range)
    ref = sc.render(vol, tf, sc.Camera.orbit(vol, 30, 20), 24, 20, background="transparent", mode="iso+dvr",
                    iso=values)
    assert ref.stats["shading"]  # on by default for the iso modes, from the CLI too
    np.testing.assert_allclose(np.load(arr), ref.rgba, atol=1e-6)
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--mode", "iso",
                           "-o", str(tmp_path / "none.png"))
    assert code == 2 and "needs isovalues" in err and not (tmp_path / "none.png").exists()


def test_isovalue_outside_the_data_warns(monkeypatch, capsys, tmp_path, small_volume_file):
    """An isovalue outside the value range renders the documented background image, with a
    warning that says why (one value of several: no surface for it)."""
    vol = sc.load_volume(small_volume_file)
    lo, hi = vol.value_range
    far = hi + 10.0 * (hi - lo)
    arr = tmp_path / "far.npy"
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--size", "16x16", "--mode", "iso",
                           "--iso", repr(far), "--background", "transparent", "-o", str(tmp_path / "far.png"),
                           "--array", str(arr))
    assert code == 0, err
    assert "warning:" in err and f"{far:g}" in err and "outside the value range" in err
    assert "background only" in err
    assert not np.load(arr).any()  # transparent background: nothing drawn
    mid = lo + 0.5 * (hi - lo)
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--size", "16x16", "--mode", "iso",
                           "--iso", repr(mid), "--iso", repr(far), "-o", str(tmp_path / "two.png"))
    assert code == 0, err
    assert "no surface for it" in err and f"{mid:g}" not in err.split("warning:")[1]
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--size", "16x16", "--mode", "iso",
                           "--iso", repr(mid), "-o", str(tmp_path / "in.png"))
    assert code == 0 and "warning:" not in err


def test_default_threshold_rises_above_a_background_peak(monkeypatch, capsys, tmp_path):
    """A scan whose background noise sits at 30 % of its range: the default (--threshold
    auto) shows the object and leaves the box's empty corners clear; 0.1 fogs the box."""
    rng = np.random.default_rng(5)
    a = rng.normal(0.3, 0.02, (24, 24, 24))
    z, y, x = np.indices(a.shape)
    a[(x - 12) ** 2 + (y - 12) ** 2 + (z - 12) ** 2 < 5 ** 2] = 0.8
    a[0, 0, 0], a[-1, -1, -1] = 0.0, 1.0
    path = tmp_path / "scan.npy"
    np.save(path, np.clip(a, 0, 1).astype(np.float32))
    images = {}
    for name, extra in (("auto", ()), ("fixed", ("--threshold", "0.1"))):
        arr = tmp_path / f"{name}.npy"
        code, _, err = run_cli(monkeypatch, capsys, "render", str(path), "--size", "32x32", "--background",
                               "transparent", "-o", str(tmp_path / f"{name}.png"), "--array", str(arr), *extra)
        assert code == 0, err
        images[name] = np.load(arr)[..., 3]
    # a pixel whose ray crosses the box beside the ball (the ball's silhouette is the centre)
    corner = (8, 6)
    assert images["fixed"][corner] > 0.3
    assert images["auto"][corner] < 0.01
    assert images["auto"][16, 16] > 0.5


def test_a_threshold_that_is_not_a_number_is_one_clear_error(monkeypatch, capsys, tmp_path, small_volume_file):
    out = tmp_path / "x.png"
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--threshold", "0,2", "-o", str(out))
    assert code != 0 and "--threshold" in err and "'0,2'" in err and "auto" in err
    assert not out.exists()
