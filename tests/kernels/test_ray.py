"""The one slab routine and the lattice clip with half-open faces, against brute force."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from sparsecast.kernels.ray import (BOX_ROWS, clip_box, clip_box_list, clip_lattice, compact_spans, inverse,
                                    lattice_range)


def _brute(o, d, lo, hi, open_lo, open_hi, dt, k_max=400):
    """Lattice indices whose t passes every face's own test (t-space, per axis)."""
    ks = []
    for k in range(0, k_max):
        ok = True
        for a in range(3):
            if d[a] == 0.0:
                ok &= lo[a] <= o[a] <= hi[a]
                ok &= not (open_lo[a] and o[a] == lo[a]) and not (open_hi[a] and o[a] == hi[a])
                continue
            inv = 1.0 / d[a]
            ta, tb = (lo[a] - o[a]) * inv, (hi[a] - o[a]) * inv
            oa, ob = open_lo[a], open_hi[a]
            if inv < 0:
                ta, tb, oa, ob = tb, ta, ob, oa
            ok &= (k > math.floor(ta / dt)) if oa else (k >= math.ceil(ta / dt))
            ok &= (k < math.ceil(tb / dt)) if ob else (k <= math.floor(tb / dt))
        if ok:
            ks.append(k)
    return ks


coords = st.sampled_from([-3.0, 0.0, 1.0, 2.5, 4.0, 7.0])
dirs = st.sampled_from([-1.0, -0.5, 0.0, 0.25, 1.0, 2.0])


@given(o=st.tuples(coords, coords, coords), d=st.tuples(dirs, dirs, dirs),
       lo=st.tuples(coords, coords, coords), ext=st.tuples(*(st.sampled_from([0.0, 1.0, 3.0, 5.5]),) * 3),
       open_lo=st.tuples(st.booleans(), st.booleans(), st.booleans()),
       open_hi=st.tuples(st.booleans(), st.booleans(), st.booleans()),
       dt=st.sampled_from([0.25, 0.5, 1.0, 0.3]))
def test_clip_lattice_matches_brute_force(o, d, lo, ext, open_lo, open_hi, dt):
    if not any(d):
        d = (1.0, d[1], d[2])
    lo = np.array(lo)
    hi = lo + np.array(ext)
    k0, k1, t_lo, t_hi = clip_lattice(*o, *d, *lo, *hi, *open_lo, *open_hi, True, dt)
    got = list(range(k0, k1 + 1))
    assert got == _brute(o, d, lo, hi, open_lo, open_hi, dt)
    # All faces closed: exactly the lattice range of clip_box's interval.
    c0, c1, _, _ = clip_lattice(*o, *d, *lo, *hi, *(False,) * 6, False, dt)
    tn, tf = clip_box(*o, *d, *lo, *hi)
    r0, r1 = lattice_range(tn, tf, dt)
    assert (list(range(c0, c1 + 1))) == list(range(r0, r1 + 1))


def test_axis_parallel_ray_on_a_face():
    lo, hi = np.zeros(3), np.full(3, 4.0)
    k0, k1, _, _ = clip_lattice(0.0, 2.0, -1.0, 0.0, 0.0, 1.0, *lo, *hi, *(False,) * 6, False, 0.5)
    assert (k0, k1) == (2, 10)  # z from 0 to 4 at t = 1 .. 5
    k0, k1, _, _ = clip_lattice(0.0, 2.0, -1.0, 0.0, 0.0, 1.0, *lo, *hi, True, False, False, False, False, False, True, 0.5)
    assert k0 > k1  # the ray lies in the open x = 0 face


def _widened(o, d, lo, hi, pad, t_lo, t_hi):
    tn, tf = clip_box(*o, *d, *lo, *hi)
    return max(tn - pad, t_lo), min(tf + pad, t_hi)


@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.sampled_from([1.0, -1.0]),
       st.sampled_from([1.0, -1.0]), st.sampled_from([1.0, -1.0]))
def test_clip_box_list_equals_clip_box_bit_for_bit(seed, count, sx, sy, sz):
    # Every sign of the direction (the near/far rows swap per axis), boxes the ray
    # misses, flat boxes, and a ray starting inside some boxes.
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-4, 4, (3, count))
    hi = lo + rng.uniform(0, 3, (3, count)) * (rng.random((3, count)) > 0.1)
    boxes = np.vstack([lo, hi])
    assert boxes.shape[0] == BOX_ROWS
    o = tuple(rng.uniform(-3, 3, 3))
    d = tuple(np.array([sx, sy, sz]) * rng.uniform(0.05, 1.0, 3))
    inv = [inverse.py_func(c)[0] for c in d]
    pad, t_lo, t_hi = 1e-7, float(rng.uniform(0, 2)), float(rng.uniform(2, 20))
    out = np.full((2, count + 3), np.nan)
    clip_box_list(boxes, 0, count, *o, *inv, pad, t_lo, t_hi, out)
    for i in range(count):
        want = _widened(o, d, lo[:, i], hi[:, i], pad, t_lo, t_hi)
        assert (out[0, i], out[1, i]) == want, i
    assert np.isnan(out[:, count:]).all()  # only the first `count` columns are written
    # A run of the list from `first` lands at the front of `out`.
    first = count // 3
    part = np.full((2, count + 3), np.nan)
    clip_box_list(boxes, first, count - first, *o, *inv, pad, t_lo, t_hi, part)
    assert np.array_equal(part[:, : count - first], out[:, first:count])
    assert np.isnan(part[:, count - first:]).all()


@given(st.integers(0, 2**32 - 1), st.integers(0, 40))
def test_compact_spans_keeps_the_non_empty_intervals_in_order(seed, count):
    # Empty (t0 > t1), touching (t0 == t1) and NaN intervals (a NaN compares false:
    # dropped, as the scan that read the list before dropped it), and columns past `count`.
    rng = np.random.default_rng(seed)
    spans = rng.uniform(0, 10, (2, count + 3))
    spans[1, : count // 3] = spans[0, : count // 3]
    if count:
        spans[0, rng.integers(0, count)] = np.nan
    want = [(a, b) for a, b in zip(spans[0, :count], spans[1, :count]) if a <= b]
    tail = spans[:, count:].copy()
    m = compact_spans(spans, count)
    assert m == len(want)
    assert [(spans[0, i], spans[1, i]) for i in range(m)] == want
    assert np.array_equal(spans[:, count:], tail)  # nothing past `count` is touched
