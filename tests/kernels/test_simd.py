"""The four-lane slab and triangle tests: their vector IR against their scalar specifications, and that they are vector code."""

from __future__ import annotations

import platform

import numpy as np
import pytest
from numba import njit

from sparsecast.kernels.simd import slab4, slab4_reference, woop4, woop4_reference


@njit(cache=True)
def _both(nodes, node, rows, org, inv, t_lo, t_hi, out_v, out_s):
    return (slab4(nodes, node, rows, org, inv, t_lo, t_hi, out_v),
            slab4_reference(nodes, node, rows, org, inv, t_lo, t_hi, out_s))


@njit(cache=True)
def _both_tri(tri4, p, axes, org, shear, t_lo, t_hi, out_v, out_s):
    return (woop4(tri4, p, axes, org, shear, t_lo, t_hi, out_v),
            woop4_reference(tri4, p, axes, org, shear, t_lo, t_hi, out_s))


def _nodes(rng, n):
    """Nodes of four random boxes (SoA rows min x, y, z, max x, y, z), some slots empty."""
    lo = rng.uniform(-1.5, 1, (n, 3, 4))
    hi = lo + rng.uniform(0, 2.5, (n, 3, 4))
    nodes = np.zeros((n, 32), np.float32)
    nodes[:, :12] = lo.reshape(n, 12)
    nodes[:, 12:24] = hi.reshape(n, 12)
    empty = rng.random((n, 4)) < 0.15
    for a in range(3):
        nodes[:, 4 * a:4 * a + 4][empty] = np.inf
        nodes[:, 12 + 4 * a:16 + 4 * a][empty] = -np.inf
    return nodes


def test_slab4_equals_its_scalar_specification(rng):
    nodes = _nodes(rng, 64)
    out_v, out_s = np.empty(4, np.float32), np.empty(4, np.float32)
    seen = set()
    for _ in range(3000):
        node = int(rng.integers(0, len(nodes)))
        o = rng.uniform(-3, 3, 3)
        d = rng.normal(size=3)
        d[rng.random(3) < 0.1] = 0.0  # axis-parallel: the huge inverse
        inv = np.where(d == 0, 1e30, 1.0 / np.where(d == 0, 1.0, d))
        rows = tuple(int(r) for r in np.where(inv >= 0, [0, 4, 8], [12, 16, 20])) + \
            tuple(int(r) for r in np.where(inv >= 0, [12, 16, 20], [0, 4, 8]))
        org = tuple(np.float32(x) for x in np.r_[o, o])
        inv32 = tuple(np.float32(x) for x in np.r_[inv, inv * (1 + 2.0 ** -20)])
        t_hi = np.float32(rng.choice([np.inf, rng.uniform(0, 4)]))
        mv, ms = _both(nodes, node, rows, org, inv32, np.float32(0.0), t_hi, out_v, out_s)
        assert mv == ms
        np.testing.assert_array_equal(out_v, out_s)
        seen.add(mv)
    # No box, one, and several entered (empty slots never are).
    assert 0 in seen and {1, 2, 4, 8} <= seen and max(bin(m).count("1") for m in seen) >= 3


def test_slab4_entry_distances_are_the_true_ones(rng):
    # Against float64 slab arithmetic: the float32 lanes agree to rounding.
    nodes = _nodes(rng, 1)
    nodes[0, :12] = np.repeat([[-1.0], [-1.0], [-1.0]], 4, axis=1).ravel()
    nodes[0, 12:24] = np.repeat([[1.0], [2.0], [3.0]], 4, axis=1).ravel()
    out = np.empty(4, np.float32)
    o, d = np.array([-5.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    rows, org = (0, 4, 8, 12, 16, 20), tuple(np.float32(x) for x in np.r_[o, o])
    inv = (np.float32(1.0), np.float32(1e30), np.float32(1e30)) * 2
    mask, _ = _both(nodes, 0, rows, org, inv, np.float32(0), np.float32(np.inf), out, out.copy())
    assert mask == 0b1111
    np.testing.assert_array_equal(out, [4.0] * 4)
    mask, _ = _both(nodes, 0, rows, org, inv, np.float32(0), np.float32(3.5), out, out.copy())
    assert mask == 0  # the boxes start beyond t_hi


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="checks x86 vector instructions")
def test_slab4_compiles_to_packed_float32_instructions():
    @njit  # not cached: inspect_asm needs the code compiled in this process
    def kernel(nodes, node, o, s, out):
        rows = (0, 4, 8, 12, 16, 20)
        return slab4(nodes, node, rows, (o, o, o, o, o, o), (s, s, s, s, s, s), np.float32(0), np.float32(1), out)

    nodes = np.zeros((2, 32), np.float32)
    kernel(nodes, 1, np.float32(0.5), np.float32(2.0), np.empty(4, np.float32))
    asm = kernel.inspect_asm(kernel.signatures[0])
    for op in ("subps", "mulps", "minps", "maxps", "cmpleps"):
        assert op in asm, f"{op} missing: the four slab tests did not compile to packed float32 code"


def _shear(o, d):
    kz = int(np.argmax(np.abs(d)))
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    return (kx, ky, kz), (o[kx], o[ky], o[kz]), (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz])


def test_woop4_equals_its_scalar_specification_bit_for_bit(rng):
    # Random packets, plus a packet of a quad's two halves and its mirror whose shared
    # edges the rays cross exactly: lanes must round as the scalar test does.
    tri4 = rng.normal(size=(40, 9, 4)).astype(np.float32)
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    for lane, (a, b, c) in enumerate([(0, 1, 2), (0, 2, 3), (2, 1, 0), (3, 2, 0)]):
        tri4[0, :, lane] = np.concatenate([quad[a], quad[b], quad[c]])
    out_v, out_s = np.empty(8), np.empty(8)
    n_hit = 0
    for k in range(3000):
        p = k % 40
        if p == 0:  # through a point of the quad's diagonal
            d = rng.normal(size=3) * 0.3 + [0, 0, -1]
            d = d / np.linalg.norm(d)
            o = np.full(3, rng.uniform(0, 1)) * [1, 1, 0] - 2.0 * d
        else:
            o, d = rng.normal(size=3) * 2, rng.normal(size=3)
            d = d / np.linalg.norm(d)
        axes, org, shear = _shear(o, d)
        t_hi = float(rng.choice([np.inf, rng.uniform(0, 4)]))
        mv, ms = _both_tri(tri4, p, axes, org, shear, 0.0, t_hi, out_v, out_s)
        assert mv == ms
        np.testing.assert_array_equal(out_v, out_s)
        n_hit += mv != 0
    assert n_hit > 100


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="checks x86 vector instructions")
def test_woop4_compiles_to_packed_float64_instructions():
    @njit  # not cached: inspect_asm needs the code compiled in this process
    def kernel(tri4, p, o, s, out):
        return woop4(tri4, p, (0, 1, 2), (o, o, o), (s, s, s), 0.0, np.inf, out)

    tri4 = np.zeros((2, 9, 4), np.float32)
    kernel(tri4, 1, 0.5, 2.0, np.empty(8))
    asm = kernel.inspect_asm(kernel.signatures[0])
    for op in ("subpd", "mulpd", "divpd", "cvtps2pd"):
        assert op in asm, f"{op} missing: the packet test did not compile to packed float64 code"
    assert "fmadd" not in asm and "fmsub" not in asm  # watertightness needs the products rounded
