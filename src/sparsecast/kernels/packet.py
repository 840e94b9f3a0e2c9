"""Sixteen consecutive lattice samples of one ray at once: the SIMD half of the marching loop.

:func:`sample_packet` takes lattice samples ``k .. k + PACKET - 1`` of a ray with the
scalar loop's arithmetic (:func:`.sampler.sample`, :func:`.shade.tf_alpha`,
:func:`.shade.tf_color`), in loops over the :data:`PACKET` lanes that LLVM vectorises
(two of them, see below): where it gathers, the positions, the cell look-ups, the
interpolation and the table blend run as vector instructions. Its reads are adjacent
pairs, one load each: the trilinear corners along x (:func:`.sample.trilinear_pairs`)
and a table row's ``(r, g), (b, a)`` (:func:`.shade.tf_rgba`), as each read in such a loop is a
scalar load and an insert per lane. The loop is compiled with ``noalias`` arguments
(:class:`.vectorize.LaneLoopCompiler`); without it the gathers kept them scalar.
The operations per lane are the scalar ones in the same order, and Numba forms
no fused multiply-adds, so every lane's floats equal the scalar loop's bit for
bit. Compositing stays scalar (:func:`.march.march_segment`): it is a running
product in ``k`` and stops at early ray termination.

Lanes are samples along one ray, not one sample of sixteen rays, because every
index's intervals feed the same marching function: a packet needs nothing from
the traversal and works for every index, every interval length and early
termination. A packet that runs past its interval's end, or past the sample
where the ray terminates, computes lanes that are never composited (nor counted
as samples); their positions stay within a few steps of the volume, and every
read is clamped into it as for any sample.

With shading, :func:`shade_packet` shades the lanes the same way: the interior
path of the central-difference gradient and Blinn-Phong, lane by lane; lanes
near a face are left to the scalar :func:`.sample.gradient`.

Measured (interleaved, naive, 512², 2 threads; 2026-12-03): unshaded dense TF
mni152 249 -> 180 ms a frame, bonsai 297 -> 208 ms; shaded dense mni152
577 -> 467 ms, bonsai 696 -> 553 ms; sparse TF 1.3x. In a micro-benchmark of the
march alone (uint8, rays of about 250 samples) 51 cycles a sample scalar, 34 in
packets (AVX2 gathers for the corners and the table; the shading's byte reads
were then scalar loads). The gradient then read
its voxels as runs (:func:`.vectorize.load_run`, 12 loads instead of 32): shaded dense
mni152 622 -> 478 ms, bonsai 752 -> 528 ms (AMD EPYC, 2 threads, interleaved), shaded
/ unshaded 2.0-2.1. Corner pairs as one load each (:func:`.sample.trilinear_pairs`):
unshaded dense mni152 271/290 -> 235/250 ms, bonsai 337/342 -> 294/290 ms. A lane's
read is a gather only when it is 32 or 64 bits wide (x86 has no narrower gather): the
gradient's byte pairs are now 32-bit reads (:func:`.sample.interior_gradient`), so all
its loads are gathers, and so are a uint8 volume's trilinear corner pairs
(:func:`.sample.trilinear_pairs`: 32-bit words and a shift).

On AMD (Zen 3 here) LLVM emits no gathers: its cost model takes them to be slow
there (no ``fast-gather`` tuning), so a lane loop whose reads it would have to gather
is compiled as unrolled scalar code, all its arithmetic with it. Forcing gathers
(``NUMBA_CPU_FEATURES`` = the host's features plus ``+fast-gather``) made frames
slower, images identical: naive dense TF tooth and bonsai 512² 1.16-1.26x the CPU
time, shaded 1.18x, the k-d tree's default-TF frames 1.15x (one thread,
alternating processes, 2 rounds, 2026-12-07). Cycles per sample measured on Intel
and on AMD machines therefore differ by more than the clock.

So :func:`sample_packet` runs two lane loops, not one: the samples' values (the
voxel reads), then the table (its reads and blend). On such a CPU the first stays
scalar, while the second's position, blend and float32 conversions become vector code
around the table rows' scalar loads (as :func:`shade_packet`'s arithmetic does around
its reads); where LLVM gathers, each loop is a gather loop as the one was, with one
store and one load more per lane. Images identical. Measured (AMD EPYC Zen 3, 512²,
2 threads, alternating processes against one loop, 2026-12-07): naive dense TF, CPU
per sample unshaded 22.7-26.5 -> 14.1-15.4 ns (tooth, bonsai, mni152), shaded 52-67 ->
42-46 ns; the deep k-d tree's default-TF frames 1.1-1.4x less CPU (tooth, headsq,
neghip, mni152). Not measured on an Intel CPU with AVX-512. The value-only packets of
the isosurfaces (:func:`value_packet`) have no table; split there as well, the
corners read in one loop and interpolated in a second, they were slower (naive iso
frames 1.08-1.11x the CPU), so they stay one loop.
"""

from __future__ import annotations

import math

from numba import njit, types
from numba.extending import overload

from .borrow import NO_REFCOUNT
from .layout import layout_of
from .sample import interior_gradient, pairs_min_nx, trilinear_pairs
from .sampler import Nearest, Trilinear, sample
from .shade import SHADING_KA, SHADING_KD, SHADING_KS, SHADING_SHININESS, tf_rgba
from .vectorize import LaneLoopCompiler

__all__ = ["PACKET", "PACKET_BUFFER", "PACKET_SHADED", "SHADE_LANES", "packet_capable", "sample_packet", "shade_packet",
           "value_packet"]

#: Lanes of a packet: sixteen float64 lanes are two AVX-512 registers (four AVX2). Two
#: registers' worth of independent lanes hide more of a lane's latency (addresses, loads,
#: table gathers) than one: measured against eight (alternating processes, 512²,
#: 2026-12-06, Intel Xeon with AVX-512): naive dense-TF frames 1.1-1.2x less CPU, the
#: deep k-d tree's sparse frames 1.1-1.4x; thirty-two lanes lost again (0.7-1.0x).
PACKET = 16
#: Lanes :func:`shade_packet` shades per call: the gradient keeps many values per lane
#: live, and sixteen at once spilled (shaded frames 0.93-1.02x of eight lanes').
SHADE_LANES = 8
# Rows of the lane buffer: opacity, red, green, blue (sample_packet), then shade_packet's
# interior flag and its scratch.
_FLAG, _NDL, _LENGTH, _POW, _BASE = 4, 5, 6, 7, 8
#: Row of the lane buffer where :func:`shade_packet` marks the lanes it shaded (1.0).
PACKET_SHADED = _FLAG
#: Length of the lane buffer of :func:`sample_packet` and :func:`shade_packet`.
PACKET_BUFFER = 9 * PACKET


def packet_capable(sampler, flat) -> bool:
    """Whether samples of a sampler of Numba type ``sampler`` on voxels of Numba type
    ``flat`` are taken in packets: trilinear or nearest samples of a dense volume.
    (Typing-time: the marcher picks its loop by it, with no branch at run time.)"""
    cls = getattr(sampler, "instance_class", None)
    return ((cls is Trilinear or cls is Nearest) and layout_of(flat) == "dense"
            and isinstance(flat, types.Array) and isinstance(flat.dtype, (types.Integer, types.Float)))


# Inlined into the marcher (march.march_interval, compiled with the same pipeline): the
# call per packet weighed on frames of short segments.
@njit(cache=True, error_model="numpy", pipeline_class=LaneLoopCompiler, inline="always", **NO_REFCOUNT)
def sample_packet(sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz, dt, k, k_last, buf):
    """Classify lattice samples ``k .. min(k + PACKET - 1, k_last)`` of a ray into ``buf``.

    Parameters
    ----------
    sampler, flat, nx, ny, nz, table, v_lo, scale
        As for :func:`.march.march_segment` (a dense volume's 1-D view).
    ox, oy, oz, dx, dy, dz : float
        Ray in index space: sample ``k`` is at ``o + (k * dt) * d``.
    dt : float
        World-space lattice step.
    k : int
        Lattice index of the first lane.
    k_last : int
        Last lattice index wanted (the segment's end): lanes past it are not computed
        and keep what ``buf`` held. A scalar lane loop (a CPU where LLVM does not
        gather) computes a lane for each lane it runs, so the short segments of the
        indices' leaves no longer pay for sixteen: deep k-d tree default-TF frames
        1.01-1.16x less CPU (minima of 4-5 alternating pairs, one thread, 512², tooth,
        headsq, neghip, mni152, AMD EPYC Zen 3, 2026-12-07; images identical), naive
        dense-TF frames unchanged (0.98-1.00x).
    buf : (PACKET_BUFFER,) float64, C-contiguous (rows of PACKET lanes)
        Receives, for lane ``l`` (sample ``k + l``), the step-corrected opacity at
        ``buf[l]`` and the straight colour at ``buf[PACKET + l]``,
        ``buf[2 PACKET + l]``, ``buf[3 PACKET + l]``. Must not overlap ``flat``
        or ``table`` (the kernel is compiled ``noalias``).
    """
    # Two copies of the lane loop, the test between them: a branch on nx inside the
    # loop kept LLVM from vectorising it as well (1.2-1.5x slower). The copy for volumes
    # thinner than a pair along x is a call (_thin_sample_packet): inlined, it doubled
    # the code LLVM optimised in every marcher that inlines this one, for a rare case.
    if nx >= pairs_min_nx(flat):
        # Two lane loops, the samples' values and then the table's (see the module
        # docstring), each lane's value passing through its opacity slot.
        n = min(PACKET, k_last - k + 1)
        for lane in range(n):
            t = (k + lane) * dt
            buf[lane] = _lane_sample(sampler, flat, nx, ny, nz, ox + t * dx, oy + t * dy, oz + t * dz)
        for lane in range(n):
            _classify(table, buf[lane], v_lo, scale, lane, buf)
    else:
        _thin_sample_packet(sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz, dt, k, k_last, buf)


@njit(cache=True, error_model="numpy", pipeline_class=LaneLoopCompiler, **NO_REFCOUNT)
def _thin_sample_packet(sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz, dt, k, k_last, buf):
    """:func:`sample_packet` for ``nx < pairs_min_nx(flat)``: each lane reads its voxels
    one by one (:func:`.sampler.sample`)."""
    for lane in range(min(PACKET, k_last - k + 1)):
        t = (k + lane) * dt
        v = sample(sampler, flat, nx, ny, nz, ox + t * dx, oy + t * dy, oz + t * dz)
        _classify(table, v, v_lo, scale, lane, buf)


@njit(cache=True, error_model="numpy", pipeline_class=LaneLoopCompiler, **NO_REFCOUNT)
def value_packet(sampler, flat, nx, ny, nz, ox, oy, oz, dx, dy, dz, dt, k, k_last, buf):
    """Field values of lattice samples ``k .. min(k + PACKET - 1, k_last)`` of a ray into ``buf``.

    :func:`sample_packet` without the transfer function: lane ``l`` holds
    :func:`.sampler.sample` at ``o + ((k + l) dt) d``, the same float (the
    isosurface pair test, :func:`.iso.iso_interval`, reads its samples from here).
    Arguments as for :func:`sample_packet`; lanes past ``k_last`` are not computed
    and keep what ``buf`` held, as there (the isosurface intervals of an index's
    leaves are a few samples long); ``buf`` must not overlap ``flat``.
    """
    n = min(PACKET, k_last - k + 1)
    if nx >= pairs_min_nx(flat):  # two copies of the lane loop, as in sample_packet
        for lane in range(n):
            t = (k + lane) * dt
            buf[lane] = _lane_sample(sampler, flat, nx, ny, nz, ox + t * dx, oy + t * dy, oz + t * dz)
    else:
        for lane in range(n):
            t = (k + lane) * dt
            buf[lane] = sample(sampler, flat, nx, ny, nz, ox + t * dx, oy + t * dy, oz + t * dz)


@njit(cache=True, inline="always")
def _classify(table, v, v_lo, scale, lane, buf):
    a, r, g, b = tf_rgba(table, v, v_lo, scale)
    buf[lane] = a
    buf[PACKET + lane] = r
    buf[2 * PACKET + lane] = g
    buf[3 * PACKET + lane] = b


def _lane_sample(sampler, flat, nx, ny, nz, x, y, z):  # pragma: no cover - replaced by an overload in jitted code
    """:func:`.sampler.sample` for ``nx >= pairs_min_nx(flat)``: trilinear samples read their corners in
    pairs along x (:func:`.sample.trilinear_pairs`), nearest ones as any sample."""
    raise NotImplementedError("only callable from jitted code")


@overload(_lane_sample, inline="always")
def _lane_sample_by_type(sampler, flat, nx, ny, nz, x, y, z):
    if getattr(sampler, "instance_class", None) is Trilinear:
        return _lane_trilinear
    return _lane_any


def _lane_trilinear(sampler, flat, nx, ny, nz, x, y, z):
    return trilinear_pairs(flat, nx, ny, nz, x, y, z)


def _lane_any(sampler, flat, nx, ny, nz, x, y, z):
    return sample(sampler, flat, nx, ny, nz, x, y, z)


@njit(cache=True, error_model="numpy", pipeline_class=LaneLoopCompiler, **NO_REFCOUNT)
def shade_packet(flat, nx, ny, nz, ox, oy, oz, dx, dy, dz, dt, k, wdx, wdy, wdz, inv_spacing, shading, buf):
    """Shade the colours of a packet's lanes in ``buf`` in place (see :func:`sample_packet`).

    Lane by lane this is :func:`.shade.blinn_phong` of the field's gradient taken
    by the interior path of :func:`.sample.gradient` (a cell whose six neighbours
    lie inside the volume): the same operations in the same order, so the same
    floats. Shades the first :data:`SHADE_LANES` lanes, samples ``k ..``: for the lanes
    from ``first`` on, the caller passes ``k + first`` and the view ``buf[first:]`` (its
    rows keep their stride :data:`PACKET`), and skips the groups with no visible lane.
    (An offset inside the lane loops defeated their vectorisation: frames 2x slower.)
    A lane whose cell is near a face keeps its straight colour and gets
    ``buf[4 PACKET + lane] = 0`` (an interior lane gets 1): the caller shades it
    one sample at a time. Needs ``nx, ny, nz >= 4``: every read is clamped into
    the interior, so no lane reads outside the volume. Rows 5 to 8 of ``buf``
    are scratch.
    """
    ka = shading[SHADING_KA]
    kd = shading[SHADING_KD]
    ks = shading[SHADING_KS]
    s = shading[SHADING_SHININESS]
    isx = inv_spacing[0]
    isy = inv_spacing[1]
    isz = inv_spacing[2]
    for lane in range(SHADE_LANES):
        t = (k + lane) * dt
        x = ox + t * dx
        y = oy + t * dy
        z = oz + t * dz
        i0 = int(x)
        j0 = int(y)
        k0 = int(z)
        inside = 1 <= i0 and i0 + 2 < nx and 1 <= j0 and j0 + 2 < ny and 1 <= k0 and k0 + 2 < nz
        # Reads clamped into the interior: an outside lane computes a value nobody uses.
        base = (min(max(k0, 1), nz - 3) * ny + min(max(j0, 1), ny - 3)) * nx + min(max(i0, 1), nx - 3)
        gx, gy, gz = interior_gradient(flat, nx, nx * ny, base, x - i0, y - j0, z - k0)
        gx = gx * isx
        gy = gy * isy
        gz = gz * isz
        length = math.sqrt(gx * gx + gy * gy + gz * gz)
        ndl = abs(gx * wdx + gy * wdy + gz * wdz) / length
        buf[_FLAG * PACKET + lane] = 1.0 if inside else 0.0
        buf[_NDL * PACKET + lane] = ndl
        buf[_LENGTH * PACKET + lane] = length
        buf[_POW * PACKET + lane] = 1.0
        buf[_BASE * PACKET + lane] = ndl
    # ndl ** s as shade._power takes it: by squaring for whole s up to 1024 (the loop
    # over the exponent's bits outside the lanes, so that the lane loops vectorise).
    if 0.0 <= s <= 1024.0 and s == math.floor(s):
        n = int(s)
        while n > 0:
            if n & 1:
                for lane in range(SHADE_LANES):
                    buf[_POW * PACKET + lane] *= buf[_BASE * PACKET + lane]
            for lane in range(SHADE_LANES):
                buf[_BASE * PACKET + lane] *= buf[_BASE * PACKET + lane]
            n >>= 1
    else:
        for lane in range(SHADE_LANES):
            buf[_POW * PACKET + lane] = buf[_NDL * PACKET + lane] ** s
    flat_light = ka + kd
    for lane in range(SHADE_LANES):
        r = buf[PACKET + lane]
        g = buf[2 * PACKET + lane]
        b = buf[3 * PACKET + lane]
        ndl = buf[_NDL * PACKET + lane]
        spec = ks * buf[_POW * PACKET + lane]
        diff = ka + kd * ndl
        if buf[_LENGTH * PACKET + lane] == 0.0:
            sr, sg, sb = min(r * flat_light, 1.0), min(g * flat_light, 1.0), min(b * flat_light, 1.0)
        else:
            sr, sg, sb = min(r * diff + spec, 1.0), min(g * diff + spec, 1.0), min(b * diff + spec, 1.0)
        if buf[_FLAG * PACKET + lane] != 0.0:
            buf[PACKET + lane] = sr
            buf[2 * PACKET + lane] = sg
            buf[3 * PACKET + lane] = sb
