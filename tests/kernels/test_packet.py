"""Packets of lattice samples (kernels.packet): the marching loop with SIMD
classification equals the scalar loop bit for bit, and its lane loop is vectorised."""

from __future__ import annotations

import platform
import re

import numpy as np
import pytest
from numba import njit, typeof, types

from sparsecast.kernels.march import _shade_sample, march_interval
from sparsecast.kernels.packet import PACKET, PACKET_BUFFER, sample_packet, shade_packet, value_packet
from sparsecast.kernels.ray import lattice_range
from sparsecast.kernels.sampler import Nearest, Trilinear, sample
from sparsecast.kernels.shade import tf_alpha, tf_color
from sparsecast.kernels.vectorize import LaneLoopCompiler


@njit
def _scalar_march(sampler, flat, nx, ny, nz, table, v_lo, scale, ray, wd, inv_spacing, dt, t0, t1, k_next, k_max,
                  ert, shading):
    """The marching loop one sample at a time (what march_segment did before packets),
    compositing on the transmittance as the marcher does (march.over_trans)."""
    ox, oy, oz, dx, dy, dz = ray
    k0, k1 = lattice_range(t0, t1, dt)
    k0 = max(k0, k_next)
    k1 = min(k1, k_max)
    acc_r = acc_g = acc_b = acc_a = 0.0
    if k0 > k1:
        return acc_r, acc_g, acc_b, acc_a, k_next, 0, 0
    ns = 0
    nne = 0
    trans = 1.0
    k = k0
    while k <= k1 and 1.0 - trans < ert:
        t = k * dt
        x = ox + t * dx
        y = oy + t * dy
        z = oz + t * dz
        i, f, a = tf_alpha(table, sample(sampler, flat, nx, ny, nz, x, y, z), v_lo, scale)
        ns += 1
        if a > 0.0:
            nne += 1
            r, g, b = tf_color(table, i, f)
            if shading[0] != 0.0:
                r, g, b = _shade_sample(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z, r, g, b,
                                        wd[0], wd[1], wd[2], inv_spacing, shading)
            w = trans * a
            acc_r += w * r
            acc_g += w * g
            acc_b += w * b
            trans *= 1.0 - a
        k += 1
    return acc_r, acc_g, acc_b, 1.0 - trans, k, ns, nne


@njit
def _store(row, res):
    row[0], row[1], row[2], row[3] = res[0], res[1], res[2], res[3]
    row[4], row[5], row[6] = res[4], res[5], res[6]


@njit
def _both(sampler, flat, nx, ny, nz, table, v_lo, scale, rays, spans, inv_spacing, dt, ert, shading):
    out = np.empty((rays.shape[0], 2, 7))
    for i in range(rays.shape[0]):
        ox, oy, oz, dx, dy, dz = rays[i, 0], rays[i, 1], rays[i, 2], rays[i, 3], rays[i, 4], rays[i, 5]
        t0, t1 = spans[i, 0], spans[i, 1]
        k_next, k_max = np.int64(spans[i, 2]), np.int64(spans[i, 3])
        packed = march_interval(sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz,
                                0.0, 0.6, 0.8, inv_spacing, dt, t0, t1, k_next, k_max, 0.0, 0.0, 0.0, 0.0,
                                ert, shading)
        scalar = _scalar_march(sampler, flat, nx, ny, nz, table, v_lo, scale, (ox, oy, oz, dx, dy, dz),
                               (0.0, 0.6, 0.8), inv_spacing, dt, t0, t1, k_next, k_max, ert, shading)
        _store(out[i, 0], packed)
        _store(out[i, 1], scalar)
    return out


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
@pytest.mark.parametrize("sampler", [Trilinear(), Nearest()], ids=["trilinear", "nearest"])
@pytest.mark.parametrize("shaded", [False, True], ids=["unshaded", "shaded"])
def test_packets_equal_scalar_marching(dtype, sampler, shaded):
    """Intervals of 0 to 40 samples (packets cut anywhere, partial last packets), rays
    starting outside and grazing faces, early termination inside a packet, k_next/k_max
    trimming: every float, the next index and both counts are the scalar loop's."""
    rng = np.random.default_rng(11)
    nz, ny, nx = 14, 11, 9
    data = (rng.random((nz, ny, nx)) * 200).astype(dtype)
    data[:, :, :3] = 0  # a transparent slab: zero-opacity samples inside packets
    table = np.zeros((64, 4), np.float32)
    table[:, :3] = rng.random((64, 3))
    table[8:, 3] = rng.uniform(0.0, 0.6, 56)  # values under 8 are transparent
    n = 3000
    org = rng.uniform(-2.0, [nx + 1.0, ny + 1.0, nz + 1.0], (n, 3))
    d = rng.normal(size=(n, 3))
    d[: n // 10, 1:] = 0.0  # parallel to x
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rays = np.concatenate([org, d], axis=1)
    dt = 0.37
    t0 = rng.uniform(0.0, 8.0, n)
    spans = np.stack([t0, t0 + rng.uniform(-0.5, 40 * dt, n), np.floor(t0 / dt) + rng.integers(0, 3, n),
                      np.floor(t0 / dt) + rng.integers(0, 60, n)], axis=1)
    ert = 0.9 if not shaded else 0.97
    shading = np.array([1.0 if shaded else 0.0, 0.2, 0.7, 0.3, 24.0])
    out = _both(sampler, data.reshape(-1), nx, ny, nz, table, 0.0, 64 / 200, rays, spans, np.ones(3), dt, ert,
                shading)
    packed, scalar = out[:, 0], out[:, 1]
    assert np.array_equal(packed, scalar)
    counts = scalar[:, 5]
    assert (counts > PACKET).sum() > 100 and (counts == 0).sum() > 10  # long and empty runs both occur
    assert (scalar[:, 3] >= ert).sum() > 50  # early termination happened


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
@pytest.mark.parametrize("nx", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("shaded", [False, True], ids=["unshaded", "shaded"])
def test_packets_on_thin_volumes(dtype, nx, shaded):
    """Under two voxels along x the packets read corners one by one (a pair would run past
    the row), 8-bit ones under four (a word of four would); above that in pairs, 8-bit
    pairs shifted out of the row's last four voxels in its last two cells; under four a
    side they shade lane by lane with the scalar gradient: the scalar loop's floats in
    every case."""
    rng = np.random.default_rng(nx)
    nz, ny = 9, 7
    data = (rng.random((nz, ny, nx)) * 200).astype(dtype)
    table = np.zeros((64, 4), np.float32)
    table[:, :3] = rng.random((64, 3))
    table[8:, 3] = rng.uniform(0.0, 0.3, 56)
    n = 2000
    org = rng.uniform(-1.0, [nx + 0.5, ny + 1.0, nz + 1.0], (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    dt = 0.29
    t0 = rng.uniform(0.0, 4.0, n)
    spans = np.stack([t0, t0 + rng.uniform(0.0, 30 * dt, n), np.floor(t0 / dt), np.floor(t0 / dt) + 40], axis=1)
    shading = np.array([1.0 if shaded else 0.0, 0.2, 0.7, 0.3, 24.0])
    out = _both(Trilinear(), data.reshape(-1), nx, ny, nz, table, 0.0, 64 / 200, np.concatenate([org, d], axis=1),
                spans, np.ones(3), dt, 0.95, shading)
    assert np.array_equal(out[:, 0], out[:, 1])
    assert (out[:, 1, 6] > PACKET).sum() > 100  # many rays composited more than a packet


def _packed_double_ops(dispatcher, sig) -> int:
    asm = dispatcher.inspect_asm(sig)
    name = dispatcher.overloads[sig].fndesc.llvm_func_name
    start = asm.index(f"\n{name}:")
    body = asm[start:asm.index(".Lfunc_end", start)]
    return len(re.findall(r"\bv?(?:mul|add|sub)pd\b", body))


def _function_ir(dispatcher, sig) -> str:
    """The optimised LLVM IR of the body of ``dispatcher``'s compiled ``sig`` (its own function only)."""
    name = dispatcher.overloads[sig].fndesc.llvm_func_name
    ir = dispatcher.inspect_llvm(sig)
    start = ir.index(f"@{name}(")
    return ir[start:ir.index("\n}\n", start)]


@pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                    reason="counts x86 packed-double instructions in the assembly")
def test_lane_loop_is_vectorised():
    """The packet's lane loop compiles to packed double arithmetic because its
    arguments are noalias; the control, the same loop through Numba's default
    pipeline, stays scalar (LLVM cannot bound the gathers' addresses)."""
    sig = (typeof(Trilinear()), types.uint8[::1], types.int64, types.int64, types.int64, types.float32[:, ::1],
           types.float64, types.float64, *([types.float64] * 7), types.int64, types.int64, types.float64[::1])
    opts = {k: v for k, v in sample_packet.targetoptions.items() if k not in ("cache", "nopython")}
    # compiled again uncached (a copy loaded from the disk cache keeps no assembly)
    fresh = njit(pipeline_class=LaneLoopCompiler, **opts)(sample_packet.py_func)
    fresh.compile(sig)
    control = njit(**opts)(sample_packet.py_func)
    control.compile(sig)
    assert _packed_double_ops(fresh, sig) >= 7  # at least the trilinear interpolation's multiplies
    assert _packed_double_ops(control, sig) == 0


@pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                    reason="counts x86 packed-double instructions in the assembly")
def test_marcher_inlines_the_vectorised_lane_loop():
    """sample_packet is inlined into march_interval (no call per packet), and its lane
    loop still compiles to packed double arithmetic there."""
    f64, i64 = types.float64, types.int64
    sig = (typeof(Trilinear()), types.uint8[::1], i64, i64, i64, types.float32[:, ::1], f64, f64,
           *([f64] * 9), types.float64[::1], f64, f64, f64, i64, i64, *([f64] * 5), types.float64[::1])
    opts = {k: v for k, v in march_interval.targetoptions.items() if k not in ("cache", "nopython")}
    # uncached (a cached copy keeps no assembly), with its pipeline (not in targetoptions)
    fresh = njit(pipeline_class=LaneLoopCompiler, **opts)(march_interval.py_func)
    fresh.compile(sig)
    assert _packed_double_ops(fresh, sig) >= 7  # at least the trilinear interpolation's multiplies
    # No call to sample_packet is left, nor to any other helper of the per-sample path:
    # the small ones (_axis, lerp8, _table_position, ...) are plain @njit functions that
    # LLVM must inline. What is left is the gradient near a face, the packet's shading and
    # the packet's copy for thin volumes.
    body = _function_ir(fresh, sig)
    called = {re.sub(r"B\d+v\d+.*", "", m) for m in re.findall(r"call [^@\n]*@\"?(_ZN10sparsecast[\w.$]+)", body)}
    assert called == {"_ZN10sparsecast7kernels6sample8gradient", "_ZN10sparsecast7kernels6packet12shade_packet",
                      "_ZN10sparsecast7kernels6packet19_thin_sample_packet"}, called


def _avx512() -> bool:
    import llvmlite.binding as ll

    return "+avx512f" in ll.get_host_cpu_features().flatten().split(",")


def _fresh_sample_packet():
    sig = (typeof(Trilinear()), types.uint8[::1], types.int64, types.int64, types.int64, types.float32[:, ::1],
           types.float64, types.float64, *([types.float64] * 7), types.int64, types.int64, types.float64[::1])
    opts = {k: v for k, v in sample_packet.targetoptions.items() if k not in ("cache", "nopython")}
    fresh = njit(pipeline_class=LaneLoopCompiler, **opts)(sample_packet.py_func)
    fresh.compile(sig)
    return fresh, sig


def test_lane_loops_ask_for_wide_vectors():
    """The lane loops carry LLVM's ``prefer-vector-width`` attribute (any host)."""
    fresh, sig = _fresh_sample_packet()
    name = fresh.overloads[sig].fndesc.llvm_func_name
    ir = fresh.inspect_llvm(sig)
    define = next(line for line in ir.splitlines() if line.startswith("define") and f"@{name}(" in line)
    group = re.search(r"(#\d+) \{$", define).group(1)  # the optimised module lists attributes in groups
    attributes = next(line for line in ir.splitlines() if line.startswith(f"attributes {group} ="))
    assert '"prefer-vector-width"="512"' in attributes


@pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64") or not _avx512(),
                    reason="looks for AVX-512 registers in x86 assembly")
def test_lane_loop_uses_zmm_registers():
    """On an AVX-512 CPU the float64 lanes go in zmm registers (eight a register): LLVM's
    default for such Intel CPUs (256-bit vectors, ymm halves) is overridden."""
    fresh, sig = _fresh_sample_packet()
    asm = fresh.inspect_asm(sig)
    name = fresh.overloads[sig].fndesc.llvm_func_name
    start = asm.index(f"\n{name}:")
    body = asm[start:asm.index(".Lfunc_end", start)]
    assert re.search(r"\bv(?:mul|add|sub)pd\b[^\n]*%zmm", body)


_BYTE_SIGS = {
    "shade_packet": (types.uint8[::1], types.int64, types.int64, types.int64, *([types.float64] * 7), types.int64,
                     types.float64, types.float64, types.float64, types.float64[::1], types.float64[::1],
                     types.float64[::1]),
    "sample_packet": (typeof(Trilinear()), types.uint8[::1], types.int64, types.int64, types.int64,
                      types.float32[:, ::1], types.float64, types.float64, *([types.float64] * 7), types.int64,
                      types.int64, types.float64[::1]),
    "value_packet": (typeof(Trilinear()), types.uint8[::1], types.int64, types.int64, types.int64,
                     *([types.float64] * 7), types.int64, types.int64, types.float64[::1]),
}


@pytest.mark.parametrize("kernel", [shade_packet, sample_packet, value_packet], ids=lambda k: k.__name__)
def test_lanes_read_byte_voxels_as_32_bit_words(kernel):
    """The packets read a uint8 volume's voxel pairs from 32-bit words: the gradient's as
    the middle of four (:func:`sparsecast.kernels.sample._pair`), the trilinear corners'
    by a shift (:func:`sparsecast.kernels.sample.trilinear_pairs`), which LLVM gathers;
    a 16-bit read is a scalar load and an insert per lane (any host: the loads' width
    in the IR)."""
    sig = _BYTE_SIGS[kernel.__name__]
    opts = {k: v for k, v in kernel.targetoptions.items() if k not in ("cache", "nopython")}
    fresh = njit(pipeline_class=LaneLoopCompiler, **opts)(kernel.py_func)
    fresh.compile(sig)
    body = _function_ir(fresh, sig)
    assert not re.search(r"load i16|i16> @llvm\.masked\.gather", body)
    assert re.search(r"load i32|i32> @llvm\.masked\.gather", body)


def test_sample_packet_lanes():
    """Each lane holds sample k + lane's opacity and straight colour."""
    rng = np.random.default_rng(2)
    data = (rng.random((6, 7, 8)) * 255).astype(np.uint8)
    table = rng.random((256, 4)).astype(np.float32)
    buf = np.full(PACKET_BUFFER, np.nan)
    ray = (0.3, 0.5, 0.2, 0.6, 0.5, 0.62)
    dt, k = 0.25, 3

    @njit
    def one(flat, t):
        x, y, z = ray[0] + t * ray[3], ray[1] + t * ray[4], ray[2] + t * ray[5]
        i, f, a = tf_alpha(table, sample(Trilinear(), flat, 8, 7, 6, x, y, z), 0.0, 1.0)
        r, g, b = tf_color(table, i, f)
        return a, r, g, b

    sample_packet(Trilinear(), data.reshape(-1), 8, 7, 6, table, 0.0, 1.0, *ray, dt, k, k + PACKET - 1, buf)
    for lane in range(PACKET):
        expect = one(data.reshape(-1), (k + lane) * dt)
        assert tuple(buf[lane:4 * PACKET:PACKET]) == expect


@pytest.mark.parametrize("nx", [8, 2], ids=["pairs", "thin"])
def test_sample_packet_stops_at_k_last(nx):
    """Lanes past ``k_last`` (a segment's end) are not computed: they keep what the buffer
    held; the lanes up to it are the samples (both lane loops: pairs and thin volumes)."""
    rng = np.random.default_rng(4)
    data = (rng.random((6, 7, nx)) * 255).astype(np.uint8)
    table = rng.random((256, 4)).astype(np.float32)
    ray = (0.3, 0.5, 0.2, 0.6 if nx > 2 else 0.05, 0.5, 0.62)
    dt, k = 0.25, 3
    flat = data.reshape(-1)
    full = np.full(PACKET_BUFFER, np.nan)
    sample_packet(Trilinear(), flat, nx, 7, 6, table, 0.0, 1.0, *ray, dt, k, k + PACKET - 1, full)
    for last in (k, k + 2, k + PACKET - 2):
        buf = np.full(PACKET_BUFFER, -7.0)
        sample_packet(Trilinear(), flat, nx, 7, 6, table, 0.0, 1.0, *ray, dt, k, last, buf)
        n = last - k + 1
        for row in range(4):
            assert np.array_equal(buf[row * PACKET:row * PACKET + n], full[row * PACKET:row * PACKET + n])
            assert np.all(buf[row * PACKET + n:(row + 1) * PACKET] == -7.0)


@pytest.mark.parametrize("shape", [(6, 7, 8), (5, 4, 1)])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_value_packet_lanes(shape, dtype):
    """Each lane of value_packet holds sample k + lane's field value, the scalar
    sampler's float bit for bit (both lane loops: x extent 1 and more)."""
    rng = np.random.default_rng(3)
    data = (rng.random(shape) * 200).astype(dtype)
    nz, ny, nx = shape
    flat = data.reshape(-1)
    buf = np.full(PACKET, np.nan)
    ray = (0.3, 0.5, 0.2, 0.1 if nx > 1 else 0.0, 0.45, 0.71)
    dt, k = 0.3, 2

    @njit
    def one(flat, t):
        return sample(Trilinear(), flat, nx, ny, nz, ray[0] + t * ray[3], ray[1] + t * ray[4], ray[2] + t * ray[5])

    value_packet(Trilinear(), flat, nx, ny, nz, *ray, dt, k, k + PACKET - 1, buf)
    got = [float(v) for v in buf]
    want = [float(one(flat, (k + lane) * dt)) for lane in range(PACKET)]
    assert got == want
    # Up to k_last only (an interval's last pair end): the lanes past it keep the buffer's.
    for last in (k, k + 3, k + PACKET - 2):
        part = np.full(PACKET, -7.0)
        value_packet(Trilinear(), flat, nx, ny, nz, *ray, dt, k, last, part)
        n = last - k + 1
        assert [float(v) for v in part[:n]] == want[:n]
        assert np.all(part[n:] == -7.0)


@pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                    reason="counts x86 packed-double instructions in the assembly")
def test_value_packet_lane_loop_is_vectorised():
    """The isosurface's value packets vectorise like sample_packet (noalias arguments):
    what made the naive iso marcher 2x faster would otherwise go unnoticed."""
    sig = _BYTE_SIGS["value_packet"]
    opts = {k: v for k, v in value_packet.targetoptions.items() if k not in ("cache", "nopython")}
    fresh = njit(pipeline_class=LaneLoopCompiler, **opts)(value_packet.py_func)
    fresh.compile(sig)
    control = njit(**opts)(value_packet.py_func)
    control.compile(sig)
    assert _packed_double_ops(fresh, sig) >= 7  # at least the trilinear interpolation's
    assert _packed_double_ops(control, sig) == 0
