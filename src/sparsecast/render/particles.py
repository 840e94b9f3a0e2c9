"""Particle rendering with a BIH over spheres (Kinkelin, after Wächter & Keller).

Each sphere (centre ``c``, radius ``r`` times ``radius_scale``) seen by a ray at
distance ``d`` from its centre contributes opacity ``alpha = opacity exp(-kappa (d / r)^2)``
for ``d <= r`` (a Gaussian footprint, ``opacity`` at the centre) and its colour: the
set's own, or a per-particle attribute through a colour map (``color_by``). Leaves
come front to back from the packed BIH's ordered traversal; within a leaf its
spheres are composited in order; early ray termination ends a ray. Spheres whose
boxes overlap may composite slightly out of order (an approximation the paper
accepts). A radius scale above 1 widens every plane by ``(scale - 1) * r_max``, so
the tree built once stays conservative for any scale.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from .._util.checks import as_float, positive_float
from ..camera import Camera
from ..elements import ParticleSet
from ..errors import ParameterError
from ..image import Image
from ..index.bih import ParticleBIH
from ..index.bih.traversal import next_leaf, push_root, set_ray, traversal_arrays
from ..kernels.camera import primary_ray
from ..kernels.parallel import run_chunks
from ..kernels.shade import write_pixel
from ..kernels.tiles import tile_bounds, tile_count
from .colormap import map_values
from .options import background_array, check_size

__all__ = ["render_particles", "DEFAULT_KAPPA", "DEFAULT_OPACITY", "DEFAULT_CMAP"]

#: default falloff: opacity exp(-4) ~ 0.02 at the rim
DEFAULT_KAPPA = 4.0
#: default opacity at a sphere's centre. Opaque centres (1, the former behaviour)
#: stop a ray at the first few particles it meets, so a halo's core is a flat
#: saturated disc of the envelope in front of it. At 0.1 a ray integrates tens of
#: particles: on the 32k-particle dark-matter halo in shared data (radius from the
#: data, 512x512) 2.6 % of the covered pixels reach alpha 0.95, against 50 % with
#: the former defaults (56 % white), and its two cores and the subhalos stand out
#: by colour; 0.2 and 0.4 already hide the second core.
DEFAULT_OPACITY = 0.1
#: colour map of color_by: its dark end recedes into a black background, so sparse
#: outskirts fade and dense knots glow
DEFAULT_CMAP = "inferno"


@njit(cache=True, inline="always")
def sphere_alpha(ox, oy, oz, dx, dy, dz, cx, cy, cz, r, kappa):
    """``exp(-kappa (d / r)^2)`` for the ray's distance ``d`` to centre ``c`` when
    ``d <= r`` and the closest point lies ahead of the origin, else 0."""
    px = cx - ox
    py = cy - oy
    pz = cz - oz
    tc = px * dx + py * dy + pz * dz
    if tc < 0.0:
        return 0.0
    qx = px - tc * dx
    qy = py - tc * dy
    qz = pz - tc * dz
    d2 = qx * qx + qy * qy + qz * qz
    r2 = r * r
    if d2 > r2:
        return 0.0
    return math.exp(-kappa * d2 / r2)


@njit(cache=True, error_model="numpy")
def particle_tile(tile, nodes, preorder, frame_lo, frame_step, root_box, depth, centers, radii, colors,
                  radius_scale, grow, kappa, opacity, cam, width, height, ert, background, out_rgba, out_tests):
    st_node, st_t, st_box, leaf_box, ro, rinv, rflat = traversal_arrays(depth)
    box = np.empty(6, np.float64)
    for a in range(3):
        box[a] = root_box[a] - grow
        box[3 + a] = root_box[3 + a] + grow
    x0, x1, y0, y1 = tile_bounds(tile, width, height)
    for py in range(y0, y1):
        for px in range(x0, x1):
            ox, oy, oz, dx, dy, dz = primary_ray(cam, px, py, width, height)
            r = 0.0
            g = 0.0
            b = 0.0
            a = 0.0
            tests = 0
            hs = 0
            if nodes.shape[0] > 0:
                set_ray(ro, rinv, rflat, ox, oy, oz, dx, dy, dz)
                hs = push_root(box, ro, rinv, rflat, 0.0, math.inf, st_node, st_t, st_box)
            while a < ert:
                leaf, t0, t1, hs = next_leaf(nodes, preorder, frame_lo, frame_step, grow, ro, rinv, rflat,
                                             st_node, st_t, st_box, hs, leaf_box)
                if leaf < 0:
                    break
                w = nodes[leaf]
                first = (w >> 32) & 0x3FFFFFFF
                count = w & 0xFFFFFFFF
                for j in range(first, first + count):
                    tests += 1
                    al = opacity * sphere_alpha(ox, oy, oz, dx, dy, dz, centers[j, 0], centers[j, 1],
                                                centers[j, 2], radii[j] * radius_scale, kappa)
                    if al > 0.0:
                        wt = (1.0 - a) * al
                        r += wt * colors[j, 0]
                        g += wt * colors[j, 1]
                        b += wt * colors[j, 2]
                        a += wt
            write_pixel(out_rgba, py, px, r, g, b, a, background)
            out_tests[py, px] = tests


def particle_kernel(nodes, preorder, frame_lo, frame_step, root_box, depth, centers, radii, colors,
                    radius_scale, grow, kappa, opacity, cam, width, height, ert, background, out_rgba, out_tests):
    """Every pixel tile of the frame, spread over threads (:func:`~sparsecast.kernels.parallel.run_chunks`)."""
    run_chunks(_particle_tiles, int(tile_count(width, height)), None, nodes, preorder, frame_lo, frame_step,
               root_box, depth, centers, radii, colors, radius_scale, grow, kappa, opacity, cam, width, height, ert,
               background, out_rgba, out_tests)


@njit(cache=True, nogil=True)
def _particle_tiles(first, last, nodes, preorder, frame_lo, frame_step, root_box, depth, centers, radii, colors,
                    radius_scale, grow, kappa, opacity, cam, width, height, ert, background, out_rgba, out_tests):
    for tile in range(first, last):
        particle_tile(tile, nodes, preorder, frame_lo, frame_step, root_box, depth, centers, radii, colors,
                      radius_scale, grow, kappa, opacity, cam, width, height, ert, background, out_rgba, out_tests)


def render_particles(
    particles: ParticleSet | ParticleBIH,
    camera: Camera,
    width: int = 512,
    height: int = 512,
    *,
    radius_scale: float = 1.0,
    kappa: float = DEFAULT_KAPPA,
    opacity: float = DEFAULT_OPACITY,
    color_by: str | np.ndarray | None = None,
    cmap: str = DEFAULT_CMAP,
    color_range: tuple[float, float] | None = None,
    ert: float = 0.99,
    background="transparent",
    variant: str = "elaborate",
    layout: str = "preorder",
) -> Image:
    """Render spheres with Gaussian opacity ``opacity exp(-kappa (d / r)^2)`` through a BIH.

    Parameters
    ----------
    particles : ParticleSet or ParticleBIH
        A set (its BIH is built here; ``stats["build_ms"]``) or a prebuilt
        :class:`~sparsecast.index.bih.ParticleBIH`, reused for any radius scale.
    camera : Camera
        In the particles' world space (``Camera.orbit(particles, ...)`` frames them).
    width, height : int
    radius_scale : float
        Interactive radius multiplier (> 0).
    kappa : float
        Falloff (>= 0): opacity at the rim is ``opacity exp(-kappa)``.
    opacity : float
        Opacity at a sphere's centre, in (0, 1] (:data:`DEFAULT_OPACITY`); lower it
        for denser sets, so that a ray sees into their cores.
    color_by : str or (n,) array_like, optional
        Colour each particle by this attribute (a name from
        ``ParticleSet.attribute_names``, e.g. ``"log_density"``, or values in the
        set's order) through ``cmap``; default: the set's colours.
    cmap : str
        matplotlib colour map for ``color_by`` (:data:`DEFAULT_CMAP`).
    color_range : (lo, hi), optional
        Attribute values at the colour map's ends; default the 1st and 99th
        percentile (``stats["color_range"]``).
    ert : float
        Early ray termination threshold in (0, 1].
    background : str or sequence
        As :func:`sparsecast.render`.
    variant, layout : str
        BIH build options when ``particles`` is a set.

    Returns
    -------
    Image
        Premultiplied RGBA; ``stats``: ``ms``, ``build_ms``, ``jit_ms`` (first-use compilation of the
        build and the renderer, kept out of both), ``sphere_tests``, the tree's sizes,
        ``opacity``, ``color_by`` and ``color_range``.
        An empty set gives the background.
    """
    if not isinstance(camera, Camera):
        raise ParameterError(f"camera: expected a sparsecast.Camera, got {type(camera).__name__}")
    width, height = check_size(width, height)
    radius_scale = positive_float(radius_scale, "radius_scale")
    kappa = as_float(kappa, "kappa", lo=0.0, expected="a non-negative number")
    opacity = as_float(opacity, "opacity", 0.0, 1.0, lo_open=True, expected="a number in (0, 1]")
    ert = as_float(ert, "ert", 0.0, 1.0, lo_open=True, expected="a number in (0, 1]")
    build_ms = 0.0
    build_jit_ms = 0.0
    if isinstance(particles, ParticleSet):
        build_jit_ms = _warm_build(particles, variant, layout)
        t0 = time.perf_counter()
        particles = ParticleBIH.build(particles, variant, layout)
        build_ms = (time.perf_counter() - t0) * 1e3
    elif not isinstance(particles, ParticleBIH):
        raise ParameterError(f"particles: expected a ParticleSet or ParticleBIH, got {type(particles).__name__}")
    colors, color_range = _colors(particles, color_by, cmap, color_range)
    p = particles.packed
    scale = float(radius_scale)
    grow = max(scale - 1.0, 0.0) * particles.max_radius
    rgba = np.empty((height, width, 4), np.float32)
    tests = np.empty((height, width), np.int32)
    args = (p.words, p.preorder, p.frame_lo, p.frame_step, p.root_box, p.depth, particles.centers,
            particles.radii, colors, scale, grow, float(kappa), float(opacity))
    bg = background_array(background)
    t0 = time.perf_counter()
    particle_kernel(*args, camera.ray_params(1, 1), 1, 1, float(ert), bg, np.empty((1, 1, 4), np.float32),
                    np.empty((1, 1), np.int32))  # compile / load outside the timing
    t1 = time.perf_counter()
    particle_kernel(*args, camera.ray_params(width, height), width, height, float(ert), bg, rgba, tests)
    ms = (time.perf_counter() - t1) * 1e3
    stats = {"ms": ms, "jit_ms": build_jit_ms + (t1 - t0) * 1e3, "build_ms": build_ms, "rays": width * height,
             "sphere_tests": int(tests.sum(dtype=np.int64)), "particles": len(particles.radii),
             "radius_scale": scale, "kappa": float(kappa), "opacity": float(opacity),
             "color_by": color_by if isinstance(color_by, str) else (None if color_by is None else "values"),
             "color_range": color_range, "width": width, "height": height,
             "index": "bih", "nodes": p.n_nodes, "bytes": p.nbytes}
    return Image(rgba, stats, tests)


def _colors(tree: ParticleBIH, color_by, cmap: str, color_range) -> tuple[np.ndarray, tuple[float, float] | None]:
    """Colours in tree order: the set's, or ``color_by`` mapped through ``cmap``."""
    if color_by is None:
        return tree.colors, None
    ps = tree.particles
    if isinstance(color_by, str):
        values = ps.attribute(color_by)
    else:
        values = np.asarray(color_by, dtype=np.float64)
        if values.shape != (len(ps),) or not np.all(np.isfinite(values)):
            raise ParameterError(f"color_by: expected an attribute name or {len(ps)} finite values, "
                                 f"got shape {values.shape}")
    rgb, vrange = map_values(values, cmap, color_range)
    return np.ascontiguousarray(rgb[tree.tree.perm]), vrange


_WARM: set[tuple[str, str]] = set()


def _warm_build(particles: ParticleSet, variant: str, layout: str) -> float:
    """Build the BIH once per process on the first few particles (the same array types),
    so that ``build_ms`` excludes first-use compilation; milliseconds spent (0 when warm)."""
    if (variant, layout) in _WARM:
        return 0.0
    t0 = time.perf_counter()
    n = min(64, len(particles.radii))
    if n:
        few = ParticleSet(particles.centers[:n].copy(), particles.radii[:n].copy(), particles.colors[:n].copy())
        ParticleBIH.build(few, variant, layout)
        _WARM.add((variant, layout))
    return (time.perf_counter() - t0) * 1e3
