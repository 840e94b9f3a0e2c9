"""Marching one run of lattice samples: the inner loop every DVR renderer shares.

The DVR driver (:mod:`sparsecast.render.driver`) calls :func:`march_interval`
once per run of touching non-empty intervals that an index yields (once per ray
for the naive index). Because all of them go through this function with the same global
lattice indices ``k``, they produce the same floats wherever they take the same
samples, and skipping a sample whose opacity is zero changes nothing.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numba.extending import overload

from .borrow import NO_REFCOUNT
from .packet import PACKET, PACKET_BUFFER, PACKET_SHADED, SHADE_LANES, packet_capable, sample_packet, shade_packet
from .ray import lattice_range
from .sampler import sample_alpha, sample_color, sample_normal
from .shade import SHADING_ENABLED, blinn_phong
from .vectorize import LaneLoopCompiler, lane_buffer


class Dvr(NamedTuple):
    """Mode marker: direct volume rendering (the default; see :mod:`.iso` for the others)."""

    tag: int = 0


@njit(cache=True, inline="always")
def over(acc_r, acc_g, acc_b, acc_a, r, g, b, a):
    """Front-to-back "over" of a straight-colour sample ``(r, g, b, a)`` behind the
    premultiplied accumulation: the one compositing step of every marching loop."""
    w = (1.0 - acc_a) * a
    return acc_r + w * r, acc_g + w * g, acc_b + w * b, acc_a + w


@njit(cache=True, inline="always")
def over_trans(acc_r, acc_g, acc_b, trans, r, g, b, a):
    """:func:`over` on the transmittance ``trans = 1 - acc_a``: what the marching loops carry.

    The loops composite one sample after another, so the step's latency is the
    loop's floor: ``acc_a + (1 - acc_a) a`` is a subtraction, a product and a sum in
    a row (about 12 cycles in float64), ``trans (1 - a)`` one product (``1 - a`` does
    not wait for the previous sample). The same quantity up to rounding (the
    NumPy reference composites :func:`over`'s way; images agree to ~1e-16), and
    every index marches through these loops, so all of them take the same floats.
    Measured (alternating processes, one thread, 512², dense TF, naive): 1.08-1.09x
    less CPU by minima on tooth, bonsai and headsq; sparse-TF k-d frames, which
    composite few samples, unchanged.
    """
    w = trans * a
    return acc_r + w * r, acc_g + w * g, acc_b + w * b, trans * (1.0 - a)


@njit(cache=True, **NO_REFCOUNT)
def _shade_sample(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z, r, g, b, wdx, wdy, wdz, inv_spacing,
                  shading):
    """Blinn-Phong colour of one sample from its central-difference normal
    (:func:`.sampler.sample_normal`: the field's gradient, or a smooth label's).

    Deliberately not inlined: keeping the six extra trilinear fetches out of the
    marching loop keeps that loop small (unshaded marching is the common case).
    """
    gx, gy, gz = sample_normal(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z)
    return blinn_phong(
        r, g, b, gx * inv_spacing[0], gy * inv_spacing[1], gz * inv_spacing[2],
        wdx, wdy, wdz, shading,
    )


# Rows of the lane buffer as unsigned offsets (see _march_packets).
_ROW_R = np.uint64(PACKET)
_ROW_G = np.uint64(2 * PACKET)
_ROW_B = np.uint64(3 * PACKET)
_ROW_SHADED = np.uint64(PACKET_SHADED * PACKET)


def march_segment(
    sampler, flat, nx, ny, nz, table, v_lo, scale,
    ox, oy, oz, dx, dy, dz,
    wdx, wdy, wdz, inv_spacing,
    dt, k_begin, k_end,
    acc_r, acc_g, acc_b, acc_a,
    ert, shading,
):  # pragma: no cover - replaced by an overload in jitted code
    """Composite lattice samples ``k_begin..k_end`` (inclusive) front to back.

    Parameters
    ----------
    sampler : Trilinear, Nearest or SmoothLabels
        How a sample reads and classifies the voxels (:mod:`.sampler`; chosen at
        compile time).
    flat, nx, ny, nz
        Voxels as a 1-D view of the C-ordered ``(nz, ny, nx)`` array, and its dims
        (see :func:`.sample.trilinear`; make the view once per tile, not per ray).
    table, v_lo, scale
        Step-corrected TF table (see :meth:`TransferFunction.opacity_table`), the
        value at entry 0 and entries per data unit.
    ox, oy, oz, dx, dy, dz : float
        Ray in *index* space: the sample ``k`` is at ``o + (k * dt) * d``, where
        ``t = k * dt`` is the world-space distance along the world ray.
    wdx, wdy, wdz : float
        Unit world-space ray direction (for shading).
    inv_spacing : (3,) float64
        ``1 / spacing`` (x, y, z), turning index gradients into world gradients.
    dt : float
        World-space lattice step.
    k_begin, k_end : int
        Inclusive range of lattice indices to visit.
    acc_r, acc_g, acc_b, acc_a : float
        Accumulated premultiplied colour and opacity so far.
    ert : float
        Early-ray-termination threshold; marching stops once ``acc_a >= ert``.
    shading : (5,) float64
        ``enabled, ka, kd, ks, shininess`` (see :mod:`.shade`).

    Returns
    -------
    acc_r, acc_g, acc_b, acc_a : float
        Updated accumulation.
    k_next : int
        First lattice index not visited (``k_end + 1`` unless terminated early).
    n_samples, n_nonempty : int
        Samples taken, and how many of them had non-zero opacity.
    """
    raise NotImplementedError("march_segment is only callable from jitted code")


@overload(march_segment, inline="always")
def _march_segment(sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz, wdx, wdy, wdz,
                   inv_spacing, dt, k_begin, k_end, acc_r, acc_g, acc_b, acc_a, ert, shading):
    # The loop is picked by type: packets where the sampler and the layout allow them.
    # Both are inlined into their caller (march_interval), as march_segment always was.
    return _march_packets if packet_capable(sampler, flat) else _march_one_by_one


def _march_packets(
    sampler, flat, nx, ny, nz, table, v_lo, scale,
    ox, oy, oz, dx, dy, dz,
    wdx, wdy, wdz, inv_spacing,
    dt, k_begin, k_end,
    acc_r, acc_g, acc_b, acc_a,
    ert, shading,
):
    """(jitted via :func:`march_segment`) :func:`march_segment` classifying (and shading) :data:`.packet.PACKET` samples at
    a time with SIMD (:mod:`.packet`), compositing them one by one."""
    n_samples = 0
    n_nonempty = 0
    shade = shading[SHADING_ENABLED] != 0.0
    # Shading in packets clamps every lane's reads into the interior (4 voxels a side).
    shade_lanes = shade and nx >= 4 and ny >= 4 and nz >= 4
    buf = lane_buffer(PACKET_BUFFER)
    # A packet fills only the lanes up to k_end; shade_packet still reads its group's
    # colours beyond them (and drops them): zeros there, not the stack's old bits.
    # Unshaded, no lane past k_end is read, and the interval pays nothing for this.
    if shade_lanes:
        for i in range(4 * PACKET):
            buf[i] = 0.0
    # The transmittance, not the opacity, across the loop (over_trans). The stop test
    # stays `acc_a < ert` on `acc_a = 1 - trans`, the float this returns and the driver
    # tests against ert: one criterion in both places, whatever the rounding of 1 - ert.
    # The subtraction is off the compositing chain (it feeds a predicted branch).
    trans = 1.0 - acc_a
    k = k_begin
    while k <= k_end and 1.0 - trans < ert:
        sample_packet(sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz, dt, k, k_end, buf)
        stop = min(k + PACKET, k_end + 1)
        # With shading, the lanes in groups of SHADE_LANES: a group is shaded as the ray
        # reaches it (none past termination) if a lane of it that is composited (before
        # `stop`) is visible; a lane left out is empty or never read, so its stale flag
        # in the buffer is never looked at below. Unshaded, the packet is one group.
        lane = 0
        while k < stop and 1.0 - trans < ert:
            group_end = min(k + SHADE_LANES, stop) if shade_lanes else stop
            if shade_lanes:
                for probe in range(lane, lane + group_end - k):
                    if buf[probe] > 0.0:
                        shade_packet(flat, nx, ny, nz, ox, oy, oz, dx, dy, dz, dt, k, wdx, wdy, wdz,
                                     inv_spacing, shading, buf[lane:])
                        break
            while k < group_end and 1.0 - trans < ert:
                # Unsigned indices: a signed one costs a test and a select per read for
                # Python's negative indexing (a third of this loop's instructions).
                u = np.uint64(lane)
                a = buf[u]
                n_samples += 1
                if a > 0.0:
                    n_nonempty += 1
                    r = buf[u + _ROW_R]
                    g = buf[u + _ROW_G]
                    b = buf[u + _ROW_B]
                    if shade and not (shade_lanes and buf[u + _ROW_SHADED] != 0.0):
                        # a lane near a face (or a volume under 4 voxels a side): one sample
                        t = k * dt
                        r, g, b = _shade_sample(
                            sampler, flat, nx, ny, nz, table, v_lo, scale, ox + t * dx, oy + t * dy, oz + t * dz,
                            r, g, b, wdx, wdy, wdz, inv_spacing, shading,
                        )
                    acc_r, acc_g, acc_b, trans = over_trans(acc_r, acc_g, acc_b, trans, r, g, b, a)
                lane += 1
                k += 1
    return acc_r, acc_g, acc_b, 1.0 - trans, k, n_samples, n_nonempty


def _march_one_by_one(
    sampler, flat, nx, ny, nz, table, v_lo, scale,
    ox, oy, oz, dx, dy, dz,
    wdx, wdy, wdz, inv_spacing,
    dt, k_begin, k_end,
    acc_r, acc_g, acc_b, acc_a,
    ert, shading,
):
    """(jitted via :func:`march_segment`) :func:`march_segment` one sample at a time (bricked volumes, smooth labels)."""
    n_samples = 0
    n_nonempty = 0
    shade = shading[SHADING_ENABLED] != 0.0
    trans = 1.0 - acc_a  # see _march_packets
    k = k_begin
    while k <= k_end and 1.0 - trans < ert:
        t = k * dt
        x = ox + t * dx
        y = oy + t * dy
        z = oz + t * dz
        a, look = sample_alpha(sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z)
        n_samples += 1
        if a > 0.0:
            n_nonempty += 1
            r, g, b = sample_color(sampler, table, look)
            if shade:
                r, g, b = _shade_sample(
                    sampler, flat, nx, ny, nz, table, v_lo, scale, x, y, z, r, g, b, wdx, wdy, wdz,
                    inv_spacing, shading,
                )
            acc_r, acc_g, acc_b, trans = over_trans(acc_r, acc_g, acc_b, trans, r, g, b, a)
        k += 1
    return acc_r, acc_g, acc_b, 1.0 - trans, k, n_samples, n_nonempty


# Not inlined (see index.interval, "Inlining"): called once per interval, and its
# signature names no index record, so one compiled (and cached) copy per sampler and
# dtype serves every index, where an inlined copy was compiled again in each record's
# ``integrate``. packet.sample_packet is inlined here (one call per packet less: k-d tree
# frames of short segments 1.0-1.15x less CPU, alternating processes, minima; tooth,
# headsq, neghip, mni152, 2026-12-06), so this is compiled as a lane loop as well
# (vectorize.LaneLoopCompiler: 512-bit vectors; its noalias promise holds, as this writes
# none of its array arguments and the packets' buffer is on its own stack).
@njit(cache=True, error_model="numpy", pipeline_class=LaneLoopCompiler, **NO_REFCOUNT)
def march_interval(
    sampler, flat, nx, ny, nz, table, v_lo, scale,
    ox, oy, oz, dx, dy, dz,
    wdx, wdy, wdz, inv_spacing,
    dt, t0, t1, k_next, k_max,
    acc_r, acc_g, acc_b, acc_a,
    ert, shading,
):
    """Composite the lattice samples with ``t0 <= k * dt <= t1`` and ``k_next <= k <= k_max``.

    The building block of every empty-space-skipping renderer: walk the non-empty
    regions (cells, leaves, bricks) front to back and call this for each region's
    ray interval, passing the returned ``k_next`` on. ``k_next`` makes a sample that
    lands exactly on a shared face count once; regions must not overlap otherwise.
    Arguments and returns are those of :func:`march_segment`, with ``k_next``
    (the first lattice index not yet visited) in place of ``k_end + 1``, and
    ``k_max`` the last lattice index the driver's clip admits.
    """
    k0, k1 = lattice_range(t0, t1, dt)
    if k0 < k_next:
        k0 = k_next
    if k1 > k_max:
        k1 = k_max
    if k0 > k1:
        return acc_r, acc_g, acc_b, acc_a, k_next, 0, 0
    return march_segment(
        sampler, flat, nx, ny, nz, table, v_lo, scale, ox, oy, oz, dx, dy, dz, wdx, wdy, wdz,
        inv_spacing, dt, k0, k1, acc_r, acc_g, acc_b, acc_a, ert, shading,
    )


@njit(cache=True, **NO_REFCOUNT)
def cap_sample(
    sampler, flat, nx, ny, nz, table, v_lo, scale,
    ox, oy, oz, dx, dy, dz,
    wdx, wdy, wdz, inv_spacing,
    dt, k, gx, gy, gz,
    acc_r, acc_g, acc_b, acc_a,
    cap,
):
    """Composite lattice sample ``k``, shaded with the clip face's normal: a clip cap.

    The driver calls this for the first sample ``k_lo`` of a ray that enters the clip
    region through a cut face (:func:`.ray.entry_face`), before any index traversal,
    and then marches from ``k + 1``: every index takes this one sample the same way,
    at its lattice point, so capping keeps the oracle. Arguments are those of
    :func:`march_segment`, with ``(gx, gy, gz)`` the face's index-space normal and
    ``cap`` the (5,) shading parameters of the cap (see :mod:`.shade`; lit even
    when the volume itself is unshaded).

    Returns
    -------
    acc_r, acc_g, acc_b, acc_a : float
        Updated accumulation.
    n_nonempty : int
        1 if the sample had non-zero opacity (it was capped), else 0.
    """
    t = k * dt
    a, look = sample_alpha(sampler, flat, nx, ny, nz, table, v_lo, scale, ox + t * dx, oy + t * dy, oz + t * dz)
    if not a > 0.0:
        return acc_r, acc_g, acc_b, acc_a, 0
    r, g, b = sample_color(sampler, table, look)
    r, g, b = blinn_phong(r, g, b, gx * inv_spacing[0], gy * inv_spacing[1], gz * inv_spacing[2],
                          wdx, wdy, wdz, cap)
    acc_r, acc_g, acc_b, acc_a = over(acc_r, acc_g, acc_b, acc_a, r, g, b, a)
    return acc_r, acc_g, acc_b, acc_a, 1
