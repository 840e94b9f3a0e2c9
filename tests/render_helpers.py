"""Scenes, TFs, cameras and the reference comparison shared by the render tests."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast import Camera, TransferFunction, Volume

from reference import reference_render

TOL = 1e-5


def render_and_reference(vol, tf, cam, width, height, **kw):
    # The reference takes every lattice sample: compare it with naive, whose per-pixel
    # sample counts it predicts (the default "auto" may skip).
    img = sc.render(vol, tf, cam, width, height, index="naive", **kw)
    ref, ref_samples = reference_render(vol, tf, cam, width, height, **kw)
    return img, ref, ref_samples


def assert_matches_reference(vol, tf, cam, width, height, **kw):
    img, ref, ref_samples = render_and_reference(vol, tf, cam, width, height, **kw)
    assert img.rgba.shape == (height, width, 4)
    assert img.rgba.dtype == np.float32
    diff = np.abs(img.rgba.astype(np.float64) - ref.astype(np.float64))
    worst = np.unravel_index(np.argmax(diff), diff.shape)
    assert diff.max() <= TOL, (
        f"max |render - reference| = {diff.max():.3g} at (row, col, ch) = {worst}: "
        f"render {img.rgba[worst[:2]]}, reference {ref[worst[:2]]}"
    )
    bad = np.argwhere(img.samples != ref_samples)
    assert bad.size == 0, (
        f"{len(bad)} pixel(s) with different sample counts, first at {tuple(bad[0])}: "
        f"render {img.samples[tuple(bad[0])]}, reference {ref_samples[tuple(bad[0])]}"
    )
    assert int(img.stats["samples"]) == int(ref_samples.sum())
    return img, ref


def random_volume(rng, shape, dtype, *, density=0.6, spacing=1.0, origin=0.0):
    vals = rng.random(shape) * (rng.random(shape) < density)
    if np.dtype(dtype) == np.uint8:
        data = np.rint(vals * 255).astype(np.uint8)
    else:
        data = vals.astype(dtype)
    return Volume(data, spacing=spacing, origin=origin)


def make_tfs(value_range):
    """A few TFs over ``value_range``: colour map, steps with ties, random ramp."""
    lo, hi = value_range
    span = hi - lo
    viridis = TransferFunction.preset("viridis", (lo, hi), threshold=0.2)
    steps = TransferFunction(
        [
            (lo, 0.0, 0.0, 0.0, 0.0),
            (lo + 0.4 * span, 1.0, 0.0, 0.0, 0.0),
            (lo + 0.4 * span, 1.0, 0.5, 0.0, 0.7),  # tie: a step up
            (lo + 0.7 * span, 0.0, 1.0, 0.0, 0.7),
            (lo + 0.7 * span, 0.0, 0.0, 1.0, 0.0),  # tie: a step down
            (hi, 0.0, 0.0, 1.0, 0.0),
        ],
        table_size=256,
    )
    r = np.random.default_rng(7)
    xs = np.sort(r.uniform(lo - 0.1 * span, hi + 0.1 * span, 5))
    pts = np.column_stack([xs, r.random((5, 3)), r.random(5) * (r.random(5) < 0.7)])
    ramp = TransferFunction(pts, (lo - 0.05 * span, hi + 0.05 * span), unit_distance=0.5)
    return [viridis, steps, ramp]




def camera_set(vol):
    """Orbit views (incl. 0/90/180/270 azimuth, +-90 elevation), exactly axis-parallel
    look-at views along +-x, +-y, +-z, and cameras inside the volume."""
    cams = {}
    for proj in ("orthographic", "perspective"):
        for az, el in [(0, 0), (90, 0), (180, 0), (270, 0), (0, 90), (0, -90), (90, 90),
                       (30, 20), (-135, -40), (45, 89.9)]:
            cams[f"orbit-{proj[:5]}-az{az}-el{el}"] = Camera.orbit(vol, az, el, projection=proj)
    c = vol.center
    L = vol.diagonal
    for axis in range(3):
        for sign in (1, -1):
            e = np.zeros(3)
            e[axis] = sign * L
            up = (0.0, 0.0, 1.0) if axis != 2 else (0.0, 1.0, 0.0)
            for proj in ("orthographic", "perspective"):
                cams[f"axis{'+-'[sign < 0]}{'xyz'[axis]}-{proj[:5]}"] = Camera.look_at(
                    c + e, c, up, projection=proj, ortho_height=0.9 * L, fov_y=40.0
                )
    lo, hi = vol.bounds
    inside = lo + (hi - lo) * np.array([0.4, 0.55, 0.45])
    cams["inside-persp"] = Camera.look_at(inside, inside + np.array([1.0, 0.4, -0.3]),
                                          projection="perspective", fov_y=100.0)
    cams["inside-ortho"] = Camera.look_at(inside, inside + np.array([-0.2, 1.0, 0.5]),
                                          projection="orthographic", ortho_height=0.5 * L)
    return cams


_SHAPE = (11, 9, 7)  # (nz, ny, nx): dims 7 x 9 x 11
_SPACING = (0.7, 1.0, 1.3)
_ORIGIN = (-3.0, 2.5, 10.0)
_CAMERA_NAMES = list(camera_set(Volume(np.zeros(_SHAPE, np.float32), _SPACING, _ORIGIN)))


# at least 2 voxels per axis: render() refuses one-voxel-thick volumes (issue 14, item 12)
_axis_len = st.sampled_from([2, 3, 4, 5, 6, 7, 8])
_angle_az = st.one_of(st.sampled_from([0.0, 90.0, 180.0, 270.0, -90.0, 360.0]),
                      st.floats(-360.0, 360.0, allow_nan=False))
_angle_el = st.one_of(st.sampled_from([0.0, 90.0, -90.0, 45.0]), st.floats(-90.0, 90.0, allow_nan=False))
_unit = st.floats(0.0, 1.0, allow_nan=False)


@st.composite
def tf_points(draw, lo=-0.2, hi=1.2):
    n = draw(st.integers(1, 5))
    # Positions on a 1e-4 grid: a span like 1e-308 between points is no TF anyone draws,
    # and TransferFunction rejects it (hypothesis found one).
    xs = sorted(draw(st.lists(st.integers(round(lo * 1e4), round(hi * 1e4)).map(lambda i: i / 1e4),
                              min_size=n, max_size=n)))
    pts = []
    for x in xs:
        r, g, b = draw(_unit), draw(_unit), draw(_unit)
        a = draw(st.one_of(st.just(0.0), st.just(1.0), _unit))
        pts.append((x, r, g, b, a))
    return pts


@st.composite
def scenes(draw):
    shape = (draw(_axis_len), draw(_axis_len), draw(_axis_len))
    seed = draw(st.integers(0, 2**32 - 1))
    density = draw(st.sampled_from([0.0, 0.3, 0.7, 1.0]))
    spacing = tuple(draw(st.sampled_from([0.5, 0.7, 1.0, 1.5])) for _ in range(3))
    origin = tuple(draw(st.sampled_from([0.0, -2.5, 3.25, 10.0])) for _ in range(3))
    rng = np.random.default_rng(seed)
    vol = random_volume(rng, shape, "float32", density=density, spacing=spacing, origin=origin)
    pts = draw(tf_points())
    tf = TransferFunction(pts, table_size=draw(st.sampled_from([256, 1024])),
                          unit_distance=draw(st.sampled_from([None, 0.5, 2.0])))
    proj = draw(st.sampled_from(["orthographic", "perspective"]))
    if draw(st.integers(0, 5)) == 0:
        lo, hi = vol.bounds
        eye = lo + (hi - lo) * np.array([draw(_unit), draw(_unit), draw(_unit)])
        direction = np.array([draw(st.sampled_from([-1.0, 0.0, 0.3, 1.0])) for _ in range(3)])
        if not np.any(direction):
            direction[0] = 1.0
        up = (0.0, 0.0, 1.0) if np.any(direction[:2]) else (0.0, 1.0, 0.0)
        cam = Camera.look_at(eye, eye + direction, up, projection=proj, fov_y=70.0,
                             ortho_height=max(vol.diagonal, 1.0))
    else:
        cam = Camera.orbit(vol, draw(_angle_az), draw(_angle_el), projection=proj,
                           zoom=draw(st.sampled_from([0.7, 1.0, 2.0])))
    kw = dict(
        dt=draw(st.one_of(st.sampled_from([0.25, 0.5, 1.0]), st.floats(0.05, 2.0))),
        ert=draw(st.sampled_from([0.99, 1.0, 0.5])),
        background=draw(st.sampled_from(["transparent", "black", (0.3, 0.6, 0.9, 0.5)])),
    )
    w, h = draw(st.integers(1, 12)), draw(st.integers(1, 12))
    return vol, tf, cam, w, h, kw

