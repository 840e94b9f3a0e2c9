"""Particle rendering through the BIH: closed forms, radius scale, loaders, edge cases."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.errors import FileFormatError, ParameterError
from sparsecast.index.bih import ParticleBIH
from sparsecast.render.colormap import map_values
from sparsecast.elements import default_particle_radius
from sparsecast.render.particles import DEFAULT_OPACITY


def closed_form(cam, w, h, centers, radii, colors, kappa, opacity=1.0):
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
        alphas.append(np.where((d2 <= r * r) & (tc >= 0), opacity * np.exp(-kappa * d2 / (r * r)), 0.0))
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
    for kappa, opacity in ((0.0, 1.0), (2.5, 1.0), (2.5, 0.3)):
        img = sc.render_particles(ps, cam, 41, 37, kappa=kappa, opacity=opacity, ert=1.0)
        ref = closed_form(cam, 41, 37, ps.centers, ps.radii, ps.colors, kappa, opacity)
        assert np.abs(img.rgba - ref).max() < 1e-5
        assert img.rgba[..., 3].max() > 0.9 * opacity and (img.rgba[..., 3] == 0).any()
    img = sc.render_particles(ps, cam, 41, 37, kappa=2.5, ert=1.0)  # the default opacity
    ref = closed_form(cam, 41, 37, ps.centers, ps.radii, ps.colors, 2.5, DEFAULT_OPACITY)
    assert np.abs(img.rgba - ref).max() < 1e-5


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
        img = sc.render_particles(tree, cam, 32, 32, radius_scale=scale, kappa=1.5, opacity=0.6, ert=1.0)
        ref = closed_form(cam, 32, 32, centers, radii * scale, colors, 1.5, 0.6)
        assert np.abs(img.rgba - ref).max() < 1e-5
    for layout in ("chunks",):
        img = sc.render_particles(ps, cam, 32, 32, kappa=1.5, opacity=1.0, ert=1.0, layout=layout, variant="basic")
        assert np.abs(img.rgba - closed_form(cam, 32, 32, centers, radii, colors, 1.5)).max() < 1e-5


def test_nbody_particles_render():
    ps = sc.datasets.nbody_particles(3000, seed=1)
    cam = sc.Camera.orbit(ps, 30, 20)
    img = sc.render_particles(ps, cam, 48, 48, background="black")
    assert np.all((img.rgba >= 0) & (img.rgba <= 1 + 1e-6))
    assert img.rgba[..., 3].min() == pytest.approx(1.0)  # black background is opaque
    # Opaque centres (its radii are small), so that early termination has fronts to stop at.
    bare = sc.render_particles(ps, cam, 48, 48, opacity=1.0)
    assert 0.01 < bare.rgba[..., 3].mean() < 0.99
    # Early termination only drops what lies behind an almost opaque front.
    full = sc.render_particles(ps, cam, 48, 48, opacity=1.0, ert=1.0)
    assert np.abs(full.rgba - bare.rgba).max() < 0.02
    assert bare.stats["sphere_tests"] <= full.stats["sphere_tests"]


def test_empty_and_identical_particles():
    cam = sc.Camera.look_at([0.0, -5.0, 0.0], [0.0, 0.0, 0.0], projection="orthographic", ortho_height=2.0)
    empty = sc.ParticleSet(np.zeros((0, 3)), np.zeros(0))
    img = sc.render_particles(empty, cam, 8, 8, background="white")
    assert np.array_equal(img.rgba, np.ones_like(img.rgba))
    same = sc.ParticleSet(np.zeros((5, 3)), 0.5)
    img = sc.render_particles(same, cam, 16, 16, kappa=0.0, opacity=1.0, ert=1.0)
    one = sc.render_particles(sc.ParticleSet(np.zeros((1, 3)), 0.5), cam, 16, 16, kappa=0.0, opacity=1.0, ert=1.0)
    assert img.rgba[8, 8, 3] == pytest.approx(1.0) and one.rgba[8, 8, 3] == pytest.approx(1.0)
    assert np.array_equal(img.rgba[..., 3] > 0, one.rgba[..., 3] > 0)


def test_bad_parameters():
    ps = sc.ParticleSet([[0.0, 0.0, 0.0]], 1.0)
    cam = sc.Camera.orbit(ps)
    for kw, word in (({"radius_scale": 0}, "radius_scale"), ({"kappa": -1}, "kappa"), ({"ert": 0}, "ert"),
                     ({"opacity": 0}, "opacity"), ({"opacity": 1.5}, "opacity"), ({"color_by": "log_density", "cmap": "nope"}, "cmap"),
                     ({"color_by": "log_density", "color_range": (1, 0)}, "color_range"),
                     ({"color_by": np.zeros(3)}, "color_by")):
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


def _catalogue(rng, n=400):
    """A generated star catalogue: a dense cluster in a sparse field, magnitudes brighter in the cluster."""
    cluster = rng.normal(0.0, 0.05, (n // 2, 3))
    field = rng.uniform(-1, 1, (n - n // 2, 3))
    mag = np.concatenate([rng.normal(4.0, 0.5, n // 2), rng.normal(9.0, 0.5, n - n // 2)])
    return np.concatenate([cluster, field]), mag


def test_color_by_an_attribute_through_a_colormap(rng):
    pos, mag = _catalogue(rng)
    ps = sc.ParticleSet(pos, 0.05, attributes={"mag": mag})
    cam = sc.Camera.orbit(ps, 30, 20)
    img = sc.render_particles(ps, cam, 40, 40, color_by="mag", cmap="viridis")
    lo, hi = img.stats["color_range"]
    assert (lo, hi) == pytest.approx(tuple(np.percentile(mag, [1, 99])))
    assert img.stats["color_by"] == "mag"
    # The same picture as a set whose own colours are the mapped magnitudes ...
    rgb, _ = map_values(mag, "viridis", (lo, hi))
    ref = sc.render_particles(sc.ParticleSet(pos, 0.05, rgb), cam, 40, 40)
    np.testing.assert_allclose(img.rgba, ref.rgba, atol=1e-6)
    # ... through a prebuilt tree too (its particles are in tree order), and from raw values.
    tree = ParticleBIH.build(ps)
    np.testing.assert_allclose(sc.render_particles(tree, cam, 40, 40, color_by="mag", cmap="viridis").rgba,
                               ref.rgba, atol=1e-6)
    np.testing.assert_allclose(sc.render_particles(ps, cam, 40, 40, color_by=mag, cmap="viridis").rgba,
                               ref.rgba, atol=1e-6)
    # A fixed range clamps: everything below lo takes the map's first colour.
    rgb, used = map_values(np.array([-5.0, 0.0, 1.0, 9.0]), "viridis", (0.0, 1.0))
    assert used == (0.0, 1.0)
    np.testing.assert_allclose(rgb[0], rgb[1]) and np.testing.assert_allclose(rgb[2], rgb[3])
    assert not np.allclose(rgb[1], rgb[2])


def test_unknown_attribute_names_the_available_ones(rng):
    pos, mag = _catalogue(rng, 40)
    ps = sc.ParticleSet(pos, 0.05, attributes={"mag": mag})
    with pytest.raises(ParameterError, match="no attribute 'colour'; available: mag, log_density"):
        sc.render_particles(ps, sc.Camera.orbit(ps), 8, 8, color_by="colour")
    with pytest.raises(ParameterError, match="attribute 'mag'"):
        sc.ParticleSet(pos, 0.05, attributes={"mag": mag[:3]})


def test_log_density_and_default_radius(rng):
    pos, _ = _catalogue(rng)
    ps = sc.ParticleSet(pos)  # no radii: from the data
    assert ps.radius_estimated
    rho = ps.attribute("log_density")
    assert np.median(rho[:200]) > np.median(rho[200:]) + 2  # the cluster is > 100x denser than the field
    # On a cubic lattice of spacing s the second-nearest neighbour is s away.
    g = np.arange(6) * 0.25
    lattice = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3)
    assert default_particle_radius(lattice) == pytest.approx(0.25)
    assert default_particle_radius(np.zeros((4, 3))) == pytest.approx(1e-6)  # all in one spot


def test_lower_opacity_sees_into_a_dense_core(rng):
    pos, _ = _catalogue(rng, 2000)
    ps = sc.ParticleSet(pos)
    cam = sc.Camera.orbit(ps, 30, 20)
    opaque = sc.render_particles(ps, cam, 48, 48, opacity=1.0)
    default = sc.render_particles(ps, cam, 48, 48)
    sat = lambda img: float((img.rgba[..., 3] > 0.95).mean())
    assert sat(opaque) > 0.0 and sat(default) < 0.5 * sat(opaque)


def test_attributes_from_files(tmp_path, rng):
    pos, mag = _catalogue(rng, 30)
    rows = "\n".join(f"{x},{y},{z},{m}" for (x, y, z), m in zip(pos, mag))
    (tmp_path / "stars.csv").write_text("x,y,z,mag\n" + rows + "\n")
    ps = sc.load_particles(tmp_path / "stars.csv")
    np.testing.assert_allclose(ps.attribute("mag"), mag)
    assert ps.attribute_names == ("mag", "log_density") and ps.radius_estimated and not ps.has_colors
    rec = np.zeros(30, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("mass", "<f4")])
    rec["x"], rec["y"], rec["z"], rec["mass"] = pos[:, 0], pos[:, 1], pos[:, 2], mag
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 30\nproperty float x\nproperty float y\n"
              "property float z\nproperty float mass\nend_header\n")
    (tmp_path / "p.ply").write_bytes(header.encode() + rec.tobytes())
    ps = sc.load_particles(tmp_path / "p.ply", radius=0.1)
    np.testing.assert_allclose(ps.attribute("mass"), mag, rtol=1e-6)
    assert not ps.radius_estimated and np.all(ps.radii == 0.1)
