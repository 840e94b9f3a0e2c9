"""Particle rendering through the BIH: closed forms, radius scale, loaders, edge cases."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.errors import FileFormatError, ParameterError
from sparsecast.index.bih import ParticleBIH


def closed_form(cam, w, h, centers, radii, colors, kappa):
    """Front-to-back composite of Gaussian footprints, spheres sorted by depth."""
    o, d = cam.rays(w, h)
    acc = np.zeros((h, w, 4))
    tcs = [((np.asarray(c) - o) * d).sum(-1) for c in centers]
    order = np.argsort(np.stack(tcs), axis=0)
    alphas = []
    for c, r in zip(centers, radii):
        p = np.asarray(c) - o
        tc = (p * d).sum(-1)
        q = p - tc[..., None] * d
        d2 = (q * q).sum(-1)
        alphas.append(np.where((d2 <= r * r) & (tc >= 0), np.exp(-kappa * d2 / (r * r)), 0.0))
    alphas = np.stack(alphas)
    for rank in range(len(centers)):
        idx = order[rank]
        al = np.take_along_axis(alphas, idx[None], 0)[0]
        col = np.asarray(colors)[idx]
        wgt = (1 - acc[..., 3]) * al
        acc[..., :3] += wgt[..., None] * col
        acc[..., 3] += wgt
    return acc


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_single_sphere_closed_form(projection):
    ps = sc.ParticleSet([[1.0, 2.0, -0.5]], [0.75], [[1.0, 0.5, 0.25]])
    cam = sc.Camera.look_at([1.3, -6.0, 0.0], [1.0, 2.0, -0.5], projection=projection, ortho_height=2.0,
                            fov_y=15.0)
    for kappa in (0.0, 2.5):
        img = sc.render_particles(ps, cam, 41, 37, kappa=kappa, ert=1.0)
        ref = closed_form(cam, 41, 37, ps.centers, ps.radii, ps.colors, kappa)
        assert np.abs(img.rgba - ref).max() < 1e-5
        assert img.rgba[..., 3].max() > 0.9 and (img.rgba[..., 3] == 0).any()


def test_separated_spheres_and_radius_scale():
    """Disjoint spheres along the view: exact front-to-back order; a radius scale
    equals rendering the scaled radii (the tree built once stays conservative)."""
    rng = np.random.default_rng(0)
    centers = np.stack([np.arange(6) * 3.0, rng.uniform(-0.3, 0.3, 6), rng.uniform(-0.3, 0.3, 6)], 1)
    radii = rng.uniform(0.4, 0.7, 6)
    colors = rng.uniform(0, 1, (6, 3))
    ps = sc.ParticleSet(centers, radii, colors)
    cam = sc.Camera.look_at([-10.0, 0.2, 0.1], [0.0, 0.0, 0.0], projection="orthographic", ortho_height=3.0)
    tree = ParticleBIH.build(ps)
    for scale in (0.5, 1.0, 1.4):
        img = sc.render_particles(tree, cam, 32, 32, radius_scale=scale, kappa=1.5, ert=1.0)
        ref = closed_form(cam, 32, 32, centers, radii * scale, colors, 1.5)
        assert np.abs(img.rgba - ref).max() < 1e-5
    for layout in ("chunks",):
        img = sc.render_particles(ps, cam, 32, 32, kappa=1.5, ert=1.0, layout=layout, variant="basic")
        assert np.abs(img.rgba - closed_form(cam, 32, 32, centers, radii, colors, 1.5)).max() < 1e-5


def test_nbody_particles_render():
    ps = sc.datasets.nbody_particles(3000, seed=1)
    cam = sc.Camera.orbit(ps, 30, 20)
    img = sc.render_particles(ps, cam, 48, 48, background="black")
    assert np.all((img.rgba >= 0) & (img.rgba <= 1 + 1e-6))
    assert img.rgba[..., 3].min() == pytest.approx(1.0)  # black background is opaque
    bare = sc.render_particles(ps, cam, 48, 48)
    assert 0.01 < bare.rgba[..., 3].mean() < 0.99
    # Early termination only drops what lies behind an almost opaque front.
    full = sc.render_particles(ps, cam, 48, 48, ert=1.0)
    assert np.abs(full.rgba - bare.rgba).max() < 0.02
    assert bare.stats["sphere_tests"] <= full.stats["sphere_tests"]


def test_empty_and_identical_particles():
    cam = sc.Camera.look_at([0.0, -5.0, 0.0], [0.0, 0.0, 0.0], projection="orthographic", ortho_height=2.0)
    empty = sc.ParticleSet(np.zeros((0, 3)), np.zeros(0))
    img = sc.render_particles(empty, cam, 8, 8, background="white")
    assert np.array_equal(img.rgba, np.ones_like(img.rgba))
    same = sc.ParticleSet(np.zeros((5, 3)), 0.5)
    img = sc.render_particles(same, cam, 16, 16, kappa=0.0, ert=1.0)
    one = sc.render_particles(sc.ParticleSet(np.zeros((1, 3)), 0.5), cam, 16, 16, kappa=0.0, ert=1.0)
    assert img.rgba[8, 8, 3] == pytest.approx(1.0) and one.rgba[8, 8, 3] == pytest.approx(1.0)
    assert np.array_equal(img.rgba[..., 3] > 0, one.rgba[..., 3] > 0)


def test_bad_parameters():
    ps = sc.ParticleSet([[0.0, 0.0, 0.0]], 1.0)
    cam = sc.Camera.orbit(ps)
    for kw, word in (({"radius_scale": 0}, "radius_scale"), ({"kappa": -1}, "kappa"), ({"ert": 0}, "ert")):
        with pytest.raises(ParameterError, match=word):
            sc.render_particles(ps, cam, 4, 4, **kw)
    with pytest.raises(ParameterError, match="radii"):
        sc.ParticleSet([[0.0, 0.0, 0.0]], -1.0)
    with pytest.raises(ParameterError, match="centers"):
        sc.ParticleSet([[0.0, 0.0]], 1.0)


def test_loaders(tmp_path):
    rng = np.random.default_rng(5)
    table = np.concatenate([rng.normal(size=(20, 3)), rng.uniform(0.1, 0.2, (20, 1)), rng.uniform(0, 1, (20, 3))], 1)
    np.save(tmp_path / "p.npy", table)
    ps = sc.load_particles(tmp_path / "p.npy")
    assert np.allclose(ps.centers, table[:, :3]) and np.allclose(ps.radii, table[:, 3])
    assert np.allclose(ps.colors, table[:, 4:])
    (tmp_path / "p.csv").write_text("z,y,x,radius\n" + "\n".join(",".join(map(str, r)) for r in table[:, [2, 1, 0, 3]]))
    ps = sc.load_particles(tmp_path / "p.csv")
    assert np.allclose(ps.centers, table[:, :3]) and np.allclose(ps.radii, table[:, 3])
    np.savetxt(tmp_path / "q.csv", table[:, :3], delimiter=",")
    ps = sc.load_particles(tmp_path / "q.csv", radius=0.3)
    assert np.allclose(ps.radii, 0.3)
    trimesh = pytest.importorskip("trimesh")
    cols = (rng.uniform(0, 1, (20, 4)) * 255).astype(np.uint8)
    trimesh.PointCloud(table[:, :3], colors=cols).export(tmp_path / "p.ply")
    ps = sc.load_particles(tmp_path / "p.ply")
    assert np.allclose(ps.centers, table[:, :3]) and np.allclose(ps.colors, cols[:, :3] / 255.0)
    assert np.all(ps.radii > 0)
    # radius and colour vertex properties, ASCII and binary
    header = ("ply\nformat {fmt} 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
              "property float radius\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n")
    (tmp_path / "a.ply").write_text(header.format(fmt="ascii") + "0 0 0 0.5 255 0 0\n1 2 3 0.25 0 255 0\n")
    rec = np.array([(0, 0, 0, 0.5, 255, 0, 0), (1, 2, 3, 0.25, 0, 255, 0)],
                   dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("radius", "<f4"), ("red", "u1"),
                          ("green", "u1"), ("blue", "u1")])
    (tmp_path / "b.ply").write_bytes(header.format(fmt="binary_little_endian").encode() + rec.tobytes())
    for name in ("a.ply", "b.ply"):
        ps = sc.load_particles(tmp_path / name)
        assert np.allclose(ps.centers, [[0, 0, 0], [1, 2, 3]]) and np.allclose(ps.radii, [0.5, 0.25])
        assert np.allclose(ps.colors, [[1, 0, 0], [0, 1, 0]])
    (tmp_path / "bad.xyz").write_text("1 2 3")
    with pytest.raises(FileFormatError, match="suffix"):
        sc.load_particles(tmp_path / "bad.xyz")
    np.save(tmp_path / "bad.npy", np.zeros((4, 5)))
    with pytest.raises(FileFormatError, match="columns"):
        sc.load_particles(tmp_path / "bad.npy")
    with pytest.raises(FileFormatError, match="not found"):
        sc.load_particles(tmp_path / "nope.csv")


def test_particle_build_warm_up_compiles_what_the_build_runs(monkeypatch):
    """The warm-up build on a few particles takes the first-use compilation, so the timed
    build after it compiles nothing (checked on a cold kernel cache, trivially on a warm one)."""
    from sparsecast import kernel_cache
    from sparsecast.index.bih import ParticleBIH
    from sparsecast.render import particles as particles_module

    monkeypatch.setattr(particles_module, "_WARM", set())
    ps = sc.datasets.nbody_particles(400, seed=2)
    assert particles_module._warm_build(ps, "elaborate", "preorder") > 0
    assert particles_module._warm_build(ps, "elaborate", "preorder") == 0.0
    before = kernel_cache.compile_seconds()
    ParticleBIH.build(ps, "elaborate", "preorder")
    assert kernel_cache.compile_seconds() == before
    img = sc.render_particles(ps, sc.Camera.orbit(ps), 8, 8)
    assert img.stats["jit_ms"] >= 0 and img.stats["build_ms"] > 0
