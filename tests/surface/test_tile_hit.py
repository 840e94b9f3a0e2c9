"""The height-field tile test: its hit is the ray's first crossing of the bilinear surface.

The oracle marches the ray's height minus the bilinear patch height on a fine grid
(every valid cell's patch, evaluated independently in NumPy), takes the first sign
change and bisects it to float64 precision: the kernel's closed-form root must agree,
and no earlier crossing may exist.
"""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from sparsecast.surface._rbvh_kernels import EMPTY, tile_hit
from sparsecast.surface.atlas import tile_records


def _one_tile(depth: np.ndarray):
    """Records of one ``R x R`` tile over ``[0, R-1]^2`` with heights along +z (identity frame)."""
    r = depth.shape[0]
    proj = np.array([[0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1]], np.float32)
    valid = depth[depth > EMPTY / 2]
    height = np.array([[valid.min() - 0.01, valid.max() + 0.01]], np.float32)
    rec = tile_records(proj, height, np.array([0]), np.array([r]))
    return rec, rec.view(np.int32), depth.astype(np.float32).ravel()


def _surface_gap(depth: np.ndarray, o, d, t):
    """Ray height minus the bilinear surface at parameters ``t`` (NaN off the tile or in empty cells)."""
    r = depth.shape[0]
    p = o[None] + t[:, None] * d[None]
    s, u = p[:, 0], p[:, 1]
    i = np.clip(np.floor(s).astype(int), 0, r - 2)
    j = np.clip(np.floor(u).astype(int), 0, r - 2)
    fs, ft = s - i, u - j
    h00, h10, h01, h11 = depth[j, i], depth[j, i + 1], depth[j + 1, i], depth[j + 1, i + 1]
    h = (1 - ft) * ((1 - fs) * h00 + fs * h10) + ft * ((1 - fs) * h01 + fs * h11)
    bad = (s < 0) | (s > r - 1) | (u < 0) | (u > r - 1) | (np.minimum.reduce([h00, h10, h01, h11]) < EMPTY / 2)
    return np.where(bad, np.nan, p[:, 2] - h)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31), st.integers(2, 9), st.booleans())
# Found by this test: the heights' differences taken in float32 (the root 2.3e-7 past the
# oracle's), and a ray dipping through a cell's patch and back (both ends above it: no sign change).
@example(46033844, 7, False)
@example(172, 4, False)
def test_tile_hit_is_the_first_crossing_of_the_bilinear_surface(seed, r, holes):
    rng = np.random.default_rng(seed)
    depth = rng.uniform(0.0, 1.5, (r, r))
    if holes:
        depth[rng.random((r, r)) < 0.2] = EMPTY
    if not (depth > EMPTY / 2).any():
        return
    rec, reci, flat = _one_tile(depth.astype(np.float32))
    depth = flat.reshape(r, r).astype(np.float64)  # the float32 heights the kernel sees
    # From above the tile towards a random point on it: steep, grazing and axis-parallel rays.
    target = np.array([rng.uniform(0, r - 1), rng.uniform(0, r - 1), rng.uniform(-0.2, 1.7)])
    o = target + np.array([rng.uniform(-3, 3), rng.uniform(-3, 3), rng.choice([0.05, 0.5, 3.0])])
    if rng.random() < 0.2:
        o[:2] = target[:2]  # straight down the -z axis
    d = target - o
    d /= np.linalg.norm(d)
    t_hit, s, u = tile_hit(0, *o, *d, 0.0, 20.0, rec, reci, flat)
    ts = np.linspace(0.0, 20.0, 400_001)
    g = _surface_gap(depth, o, d, ts)
    ok = np.isfinite(g[:-1]) & np.isfinite(g[1:])
    change = np.nonzero(ok & ((g[:-1] <= 0) != (g[1:] <= 0)))[0]
    if len(change) == 0:
        assert not np.isfinite(t_hit)
        return
    a, b = ts[change[0]], ts[change[0] + 1]
    for _ in range(60):  # bisect the oracle's bracket to float64 precision
        m = 0.5 * (a + b)
        if (_surface_gap(depth, o, d, np.array([m]))[0] <= 0) == (g[change[0]] <= 0):
            a = m
        else:
            b = m
    assert np.isfinite(t_hit), "the kernel missed a crossing the oracle finds"
    # A crossing within one grid step of the oracle's may be a tangent touch the grid did not resolve.
    assert abs(t_hit - a) < 1e-7 or t_hit < a, (t_hit, a)
    if abs(t_hit - a) >= 1e-7:
        assert abs(_surface_gap(depth, o, d, np.array([t_hit]))[0]) < 1e-7
    p = o + t_hit * d
    assert abs(s - p[0]) < 1e-9 and abs(u - p[1]) < 1e-9
