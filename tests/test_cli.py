"""The `sparsecast` command: main job, info, bench, and one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image as PILImage

import sparsecast as sc
from cli_runner import run_cli



@pytest.fixture
def small_volume_file(tmp_path):
    vol = sc.datasets.nbody_blobs(24, n_clusters=2, blobs_per_cluster=6, seed=3)
    path = tmp_path / "blobs.npy"
    sc.save_volume(vol, path)
    return path


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

@pytest.mark.parametrize(
    "args, names",
    [
        (["render", "--size", "0x5"], "width"),
        (["render", "--size", "abc"], "--size"),
        (["render", "--size", "100000x100000"], "width"),
        (["render", "--tf", "no-such-preset", "--size", "8x8"], "preset"),
        (["render", "--index", "no-such-index", "--size", "8x8"], "index"),
        (["render", "--index", "bih:mode", "--size", "8x8"], "bih:mode"),
        (["render", "--index", "bih:mode=sideways", "--size", "8x8"], "mode"),
        (["render", "--dt", "-1", "--size", "8x8"], "dt"),
        (["render", "--background", "mauve", "--size", "8x8"], "background"),
        (["render", "does-not-exist.nrrd"], "does-not-exist.nrrd"),
        (["info", "volume.xyz"], "volume.xyz"),
    ],
)
def test_bad_input_is_one_clear_line(monkeypatch, capsys, tmp_path, args, names):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(monkeypatch, capsys, *args)
    assert code == 2
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error:")
    assert names in lines[0]
    assert "Traceback" not in err
    assert not (tmp_path / "sparsecast.png").exists()


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


def test_info_reports_volume_facts(monkeypatch, capsys, small_volume_file):
    code, out, err = run_cli(monkeypatch, capsys, "info", str(small_volume_file), "--tf", "grayscale")
    assert code == 0, err
    assert "24 x 24 x 24" in out
    assert "float32" in out
    assert "occupancy" in out and "bricks" in out
    vol = sc.load_volume(small_volume_file)
    bricks = vol.brick_stats(8)
    tf = sc.TransferFunction.preset("grayscale", vol.value_range)
    expected = 100 * tf.classify(bricks.vmin, bricks.vmax).mean()
    assert f"{expected:.2f} %" in out


def test_info_lists_presets_and_indices(monkeypatch, capsys):
    code, out, _ = run_cli(monkeypatch, capsys, "info", "--presets")
    assert code == 0 and "bone" in out and "viridis" in out
    code, out, _ = run_cli(monkeypatch, capsys, "info", "--indices")
    assert code == 0 and "naive" in out


def test_warning_for_transparent_tf(monkeypatch, capsys, tmp_path, small_volume_file):
    tf = sc.TransferFunction([(0, 1, 1, 1, 0), (1, 1, 1, 1, 0)])
    tf_path = tf.save(tmp_path / "clear.json")
    code, _, err = run_cli(monkeypatch, capsys, "render", str(small_volume_file), "--tf", str(tf_path),
                           "--size", "8x8", "-o", str(tmp_path / "c.png"))
    assert code == 0
    assert "zero opacity" in err


def test_bench_writes_records(monkeypatch, capsys, tmp_path):
    path = tmp_path / "bench.json"
    code, out, err = run_cli(
        monkeypatch, capsys, "bench", "--dataset", "demo", "--size", "24x24", "--repeat", "1",
        "--warmup", "0", "--json", str(path),
    )
    assert code == 0, err
    assert "sparsecast bench" in out
    records = json.loads(path.read_text())
    phases = {r["phase"] for r in records}
    assert {"load", "brick_stats", "tf_classify", "build_cold", "rebuild", "render",
            "irt_build", "irt_query", "prefix_query"} <= phases
    assert {r["tf"] for r in records if r["phase"] == "render"} == {"default", "dense"}
    renders = [r for r in records if r["phase"] == "render"]
    assert renders and all(r["samples"] > 0 and r["ms"] > 0 for r in renders)
    for r in renders:
        assert r["samples_nonempty"] <= r["samples"]
        if r["method"] == "naive":
            assert r["speedup_vs_naive"] == pytest.approx(1.0)
    assert all(r["machine"]["cores"] for r in records)
    assert {r["dataset"] for r in records} == {"demo", "tf-table"}
    # Every exact index renders with ratios against naive from the same run.
    methods = {r["method"] for r in renders}
    assert methods == set(sc.available_indices())
    assert all(r["speedup_vs_naive"] is not None for r in renders)


def test_bench_plots(monkeypatch, capsys, tmp_path):
    code, out, err = run_cli(
        monkeypatch, capsys, "bench", "-d", "demo", "-m", "naive", "-m", "grid-pc", "--size", "16x16",
        "--repeat", "1", "--warmup", "0", "--no-dense", "--json", str(tmp_path / "b.json"),
        "--plot", str(tmp_path / "figs"),
    )
    assert code == 0, err
    for name in ("frame_times.png", "build_times.png"):
        with PILImage.open(tmp_path / "figs" / name) as im:
            assert im.size[0] > 200 and im.size[1] > 200


def test_sweep_plot_from_records(tmp_path):
    from sparsecast.bench.plots import write_plots

    recs = []
    for k, naive_ms, grid_ms in [(1, 100.0, 5.0), (64, 100.0, 20.0), (512, 100.0, 90.0)]:
        for m, ms in (("naive", naive_ms), ("grid-pc", grid_ms)):
            recs.append({"dataset": f"fig5b-256-k{k:04d}", "tf": "default", "method": m,
                         "phase": "render", "ms": ms})
    paths = write_plots(recs, tmp_path)
    assert [p.name for p in paths] == ["sweep_fig5b-256.png"]
    assert paths[0].stat().st_size > 1000


def test_bench_rejects_unknown_names(monkeypatch, capsys):
    code, _, err = run_cli(monkeypatch, capsys, "bench", "--dataset", "nope")
    assert code == 2 and "nope" in err
    code, _, err = run_cli(monkeypatch, capsys, "bench", "--method", "nope")
    assert code == 2 and "nope" in err


def test_parse_method_options():
    from sparsecast.bench.harness import parse_method

    assert parse_method("grid-pc:cell=8") == ("grid-pc", {"cell": 8})
    assert parse_method("lbvh:prune=None,voting=voxels") == ("lbvh", {"prune": None, "voting": "voxels"})
    assert parse_method("lbvh:prune=0.5") == ("lbvh", {"prune": 0.5})
    with pytest.raises(sc.ParameterError, match="key=value"):
        parse_method("lbvh:prune")
    with pytest.raises(sc.ParameterError, match="unknown index"):
        parse_method("octree")
