"""Honest timing: interleaved rounds, repeats, spread, cores busy, best index on medians,
cycles per sample, peers that skip, Embree's build with its first cast (no timing asserted)."""

from __future__ import annotations

import statistics
import sys
import types

import numpy as np
import pytest

from sparsecast.bench import harness
from sparsecast.bench.config import BenchConfig
from sparsecast.bench.harness import run_benchmarks
from sparsecast.bench.machine import nominal_clock_ghz
from sparsecast.bench.peers import PEERS, PeerUnavailable, load_peer
from sparsecast.bench.ratios import add_ratios
from sparsecast.bench.summary import best_rows
from sparsecast.bench.timing import interleaved


def test_interleaved_takes_turns_after_a_warm_up_round():
    calls = []

    def frame(name, own_ms=None):
        def f():
            calls.append(name)
            return name.lower(), own_ms
        return f

    runs = interleaved({"A": frame("A"), "B": frame("B", 7.0), "C": frame("C")}, repeat=3, warmup=1)
    assert calls == ["A", "B", "C"] * 4
    for name, r in runs.items():
        f = r.fields()
        assert len(f["ms_runs"]) == len(f["cpu_ms_runs"]) == 3 and r.result == name.lower()
        assert f["ms_min"] <= f["ms"] <= f["ms_max"] and f["ms"] == statistics.median(f["ms_runs"])
        assert f["ms_mad"] == statistics.median(abs(m - f["ms"]) for m in f["ms_runs"])
        assert f["cores_busy"] is None or f["cores_busy"] >= 0
    assert runs["B"].ms == [7.0] * 3  # a method's own frame time wins over the wall time


class _FakePeerScene:
    """A peer that renders black in a known 'time' and logs its frames."""

    log: list[str] = []

    def __init__(self, volume, tf, dt):
        pass

    def render(self, camera, width, height):
        self.log.append("fake")
        rgba = np.zeros((height, width, 4), np.float32)
        rgba[..., 3] = 1.0
        return rgba, 1000.0


@pytest.fixture
def fake_peer(monkeypatch):
    module = types.ModuleType("fake_peer")
    module.NAME = "fake"
    module.unavailable_reason = lambda: None
    module.Scene = _FakePeerScene
    monkeypatch.setitem(sys.modules, "fake_peer", module)
    monkeypatch.setitem(PEERS, "fake", "fake_peer")
    _FakePeerScene.log = []
    return "fake"


def test_bench_interleaves_methods_and_peers_on_one_scene(tiny_dataset, fake_peer, monkeypatch):
    order: list[str] = []
    real_render = harness.render

    def logged_render(vol, tf, cam, w, h, *, index, **kw):
        if not isinstance(index, str):  # timed frames render a built index; warm-ups a name
            order.append(index.name)
        return real_render(vol, tf, cam, w, h, index=index, **kw)

    monkeypatch.setattr(harness, "render", logged_render)
    monkeypatch.setattr(_FakePeerScene, "log", order)
    cfg = BenchConfig(datasets=[tiny_dataset], methods=["naive", "grid-pc"], sizes=[(16, 16)],
                      views=[(30.0, 20.0)], repeat=3, warmup=1, dense_tf=False, irt=False, peers=[fake_peer])
    records = run_benchmarks(cfg)
    # One warm-up round, then three timed rounds, every method and the peer in turn.
    assert order == ["naive", "grid-pc", "fake"] * 4, order
    renders = {r["method"]: r for r in records if r["phase"] == "render"}
    assert set(renders) == {"naive", "grid-pc", "fake"}
    for r in renders.values():
        assert len(r["ms_runs"]) == len(r["cpu_ms_runs"]) == 3
        assert r["ms_min"] <= r["ms"] <= r["ms_max"] and r["ms"] == statistics.median(r["ms_runs"])
        assert r["ms_mad"] >= 0 and r["cores_busy"] >= 0
        assert r["interleaved_with"] == ["naive", "grid-pc", "fake"]
    for m in ("naive", "grid-pc"):  # ours: samples, so cycles per sample where the clock is known
        r = renders[m]
        clock = r["machine"]["clock_ghz"]
        expected = r["cpu_ms"] * 1e-3 * clock * 1e9 / r["samples"] if clock and r["cpu_ms"] else None
        assert r["cycles_per_sample"] == pytest.approx(expected)
    # The best index is the argmin of the medians, and the peer's ratio is against it.
    best_ms = min(renders["naive"]["ms"], renders["grid-pc"]["ms"])
    (row,), _ = best_rows(records)
    assert row.best.method == min(("naive", "grid-pc"), key=lambda m: renders[m]["ms"])
    assert renders["fake"]["ms"] == 1000.0 and renders["fake"]["ratio_to_best"] == pytest.approx(1000.0 / best_ms)


def test_cycles_per_sample_and_peer_samples_from_records():
    machine = {"clock_ghz": 2.0}
    recs = [dict(dataset="d", tf="default", view="v", width=8, height=8, phase="render", method="naive",
                 ms=10.0, cpu_ms=20.0, samples=1_000_000, exact=True, machine=machine),
            dict(dataset="d", tf="default", view="v", width=8, height=8, phase="render", method="yt",
                 ms=40.0, cpu_ms=40.0, samples=1_500_000, peer=True, exact=False, machine=machine)]
    add_ratios(recs)
    assert recs[0]["cycles_per_sample"] == pytest.approx(20e-3 * 2e9 / 1e6)
    assert recs[1]["samples_vs_naive"] == pytest.approx(1.5) and recs[1]["ratio_to_best"] == pytest.approx(4.0)


def test_nominal_clock_prefers_the_rated_clock():
    assert nominal_clock_ghz("model name\t: Intel(R) Xeon(R) CPU @ 2.40GHz\ncpu MHz\t\t: 3100.0\n") == (2.4, "model name")
    clock, source = nominal_clock_ghz("model name\t: AMD EPYC\ncpu MHz\t\t: 2596.1\n")
    assert source in ("base_frequency", "cpuinfo_max_freq") or (clock, source) == (pytest.approx(2.5961), "cpu MHz")


def test_pyvista_peer_skips_with_the_reason_when_absent(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyvista", None)  # import pyvista raises ImportError
    with pytest.raises(PeerUnavailable, match="pyvista is not installed"):
        load_peer("pyvista")


def test_yt_sample_estimate_grows_off_axis(tiny_dataset):
    pytest.importorskip("yt")
    from sparsecast.bench import DATASETS
    from sparsecast.bench.peers import yt_peer
    from sparsecast.camera import Camera
    from sparsecast.render import render

    vol = DATASETS[tiny_dataset].load()
    tf = DATASETS[tiny_dataset].make_tf(vol)
    dt = 0.5 * float(vol.spacing.min())
    scene = yt_peer.Scene(vol, tf, dt)
    on_axis = Camera.orbit(vol, 0.0, 0.0, projection="orthographic")
    diagonal = Camera.orbit(vol, 45.0, 35.26, projection="orthographic")
    ours = render(vol, tf, on_axis, 16, 16, dt=dt, index="naive").stats["samples"]
    # Along an axis yt's 2 samples per cell are our 2 per voxel (plus its half-voxel margins
    # and entry cells); on the diagonal a ray crosses ~sqrt(3) times as many cells per length.
    assert 0.9 < scene.samples(on_axis, 16, 16) / ours < 1.3
    per_ray = [scene.samples(c, 16, 16) / max(1, render(vol, tf, c, 16, 16, dt=dt, index="naive").stats["samples"])
               for c in (on_axis, diagonal)]
    assert per_ray[1] > 1.3 * per_ray[0]


def test_embree_build_includes_the_first_cast(monkeypatch):
    from sparsecast.bench import surface
    from sparsecast.camera import Camera
    from sparsecast.surface.mesh import icosphere

    events: list[str] = []

    class Scene:
        def add_triangles(self, v, f):
            events.append("add")

        def cast_rays(self, rays):
            events.append("cast")
            return {}

    o3d = types.ModuleType("open3d")
    o3d.t = types.SimpleNamespace(geometry=types.SimpleNamespace(RaycastingScene=Scene))
    o3d.core = types.SimpleNamespace(Tensor=lambda a: a)
    monkeypatch.setitem(sys.modules, "open3d", o3d)
    mesh = icosphere(1)
    cam = Camera.orbit(mesh, 30.0, 20.0)
    diffuse = (np.zeros((4, 3), np.float32), np.ones((4, 3), np.float32))
    recs = []

    def record(**kw):
        recs.append({**kw, "after": list(events)})

    frames = surface._embree_frames(mesh, cam, 8, 8, diffuse, record, "sphere")
    build = next(r for r in recs if r["phase"] == "build")
    assert build["after"] == ["add", "cast"]  # recorded after the first cast, not before
    assert build["ms"] == pytest.approx(build["copy_ms"] + build["first_cast_ms"])
    # Its primary and diffuse frames cast the scene; the section times them in its rounds.
    runs = surface.interleaved(dict(zip(("primary", "diffuse"), frames)), 3, 1)
    assert events == ["add"] + ["cast"] * (1 + 2 * 4)
    assert all(len(r.ms) == 3 for r in runs.values())


def test_surface_section_reports_both_layouts_per_cpu_second():
    from sparsecast.bench import surface
    from sparsecast.surface.mesh import icosphere

    recs = []
    surface._bench_mesh("sphere", icosphere(3), 24, 16, 1, 0, lambda **kw: recs.append(kw))
    by = {(r["method"], r["phase"]): r for r in recs}
    for method in ("bvh", "bvh-binary"):
        build, render = by[(method, "build")], by[(method, "render")]
        assert build["layout"] == method.replace("bvh-", "").replace("bvh", "wide") and build["threads"] >= 1
        assert render["rays"] == 24 * 16 and render["threads"] >= 1
        assert render["mrays_cpu_s"] == pytest.approx(render["rays"] / render["cpu_ms"] / 1e3)
        assert by[(method, "render_diffuse")]["mrays_cpu_s"] > 0
    # The exact layouts see the same hits.
    assert by[("bvh-binary", "render")]["hits"] == by[("bvh", "render")]["hits"]
    assert by[("bvh-binary", "render")]["hit_mismatch_pct"] == 0.0
    # And the BVH over spatially split references, built from more references.
    assert by[("bvh-splits", "build")]["splits"] > 0 and by[("bvh-splits", "build")]["layout"] == "wide"
    assert by[("bvh-splits", "render")]["hits"] == by[("bvh", "render")]["hits"]
    assert by[("bvh-splits", "render")]["hit_mismatch_pct"] == 0.0
    # So do the RBVH's: the binary tree and its 4-wide collapse hold the same leaves.
    assert by[("rbvh-Q2-binary", "build")]["layout"] == "binary"
    assert by[("rbvh-Q2-binary", "build")]["tiles"] == by[("rbvh-Q2", "build")]["tiles"]
    assert by[("rbvh-Q2-binary", "build")]["nodes"] > by[("rbvh-Q2", "build")]["nodes"]
    assert by[("rbvh-Q2-binary", "render")]["hits"] == by[("rbvh-Q2", "render")]["hits"]
    try:
        import open3d  # noqa: F401
    except Exception:
        skipped = by[("embree", "skipped")]
        assert "open3d" in skipped["reason"] and "pip install" in skipped["reason"]
    else:
        assert by[("embree", "render")]["mrays_cpu_s"] > 0


def test_surface_section_interleaves_every_method_and_reports_spread(monkeypatch):
    """Each round casts every method once, primary rays first, then diffuse rays."""
    from sparsecast.bench import surface
    from sparsecast.surface.mesh import icosphere

    calls: list[str] = []
    real = surface.interleaved

    def spy(frames, repeat, warmup):
        wrapped = {m: (lambda m=m, f=f: (calls.append(m), f())[1]) for m, f in frames.items()}
        return real(wrapped, repeat, warmup)

    monkeypatch.setattr(surface, "interleaved", spy)
    monkeypatch.setitem(sys.modules, "open3d", None)  # no Embree: ours only
    recs = []
    surface._bench_mesh("sphere", icosphere(2), 16, 8, 3, 1, lambda **kw: recs.append(kw))
    methods = [r["method"] for r in recs if r["phase"] == "render"]
    assert methods[0] == "bvh" and len(methods) == len(set(methods)) >= 8
    # 1 warm-up + 3 timed rounds, each calling every method in the same order, twice.
    assert calls == (methods * 4) * 2
    for r in recs:
        if r["phase"] in ("render", "render_diffuse"):
            assert len(r["ms_runs"]) == 3 and r["ms_min"] <= r["ms"] <= r["ms_max"] and r["ms_mad"] >= 0
            assert r["cpu_ms"] > 0 and r["mrays_cpu_s"] > 0


@pytest.mark.parametrize("error, fix", [
    (ImportError("libusb-1.0.so.0: cannot open shared object file: No such file or directory"),
     "system library libusb-1.0.so.0 it loads is missing: install it (Debian/Ubuntu: apt-get install libusb-1.0-0)"),
    (ImportError("libfoo.so.3: cannot open shared object file: No such file or directory"),
     "system library libfoo.so.3 it loads is missing: install it to time"),
    (ModuleNotFoundError("No module named 'open3d'"), "pip install open3d"),
])
def test_embree_skip_names_the_fix(monkeypatch, error, fix):
    """Open3D failing to import is one skipped record whose reason says what to install:
    the system library its wheel could not load, or the package."""
    import builtins

    from sparsecast.bench import surface
    from sparsecast.surface.mesh import icosphere

    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):
        if name == "open3d" or name.startswith("open3d."):
            raise error
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)
    recs = []
    # the import fails first: no camera or rays are needed
    out = surface._embree_frames(icosphere(1), None, 4, 4, None, lambda **kw: recs.append(kw), "sphere")
    assert out is None and len(recs) == 1
    (rec,) = recs
    assert rec["phase"] == "skipped" and rec["method"] == "embree"
    assert str(error) in rec["reason"] and fix in rec["reason"]
    if "pip" not in fix:
        assert "pip install" not in rec["reason"]
