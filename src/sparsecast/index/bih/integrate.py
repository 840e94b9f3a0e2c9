"""BIH-DVR's approximate per-leaf integrators (``mode="single-sample"`` / ``"multi-sample"``).

They plug into the driver in place of the lattice march
(:func:`sparsecast.index.interval.integrate` for :class:`.traversal.BihApproxRecord`),
one call per leaf segment ``[t0, t1]``:

``single-sample``  one sample at the segment's midpoint, density
                   ``d(x) = d_c + g . (x - c)`` (``c`` the leaf box centre, ``g`` the
                   leaf's mean gradient per voxel), opacity corrected for the segment
                   length: ``a' = 1 - (1 - a_dt) ** ((t1 - t0) / dt)`` with ``a_dt`` the
                   step-corrected table entry, i.e. ``1 - (1 - a) ** (l / unit)``.
``multi-sample``   the global lattice samples inside the leaf with that density.

Between leaves (below the element threshold) these modes see nothing.
"""

from __future__ import annotations

from numba import njit
from numba.extending import overload

from ...kernels.borrow import NO_REFCOUNT
from ...kernels.ray import lattice_range
from ...kernels.shade import SHADING_ENABLED, blinn_phong, tf_alpha, tf_color
from ..interval import integrate, record_class
from .pack import DENSITY_MAX, GRAD_MAX, GRAD_ZERO
from .traversal import BihApproxRecord

__all__ = ["MODE_SINGLE", "MODE_MULTI", "leaf_payload"]

MODE_SINGLE, MODE_MULTI = 1, 2


@njit(cache=True, inline="always")
def leaf_payload(nodes, leaf, grad_scale):
    """Density in [0, 1] and gradient of a packed volume leaf."""
    w = nodes[leaf]
    d = ((w >> 48) & 0x3FFF) / DENSITY_MAX
    s = grad_scale / GRAD_MAX
    gx = ((w & 0xFFFF) - GRAD_ZERO) * s
    gy = (((w >> 16) & 0xFFFF) - GRAD_ZERO) * s
    gz = (((w >> 32) & 0xFFFF) - GRAD_ZERO) * s
    return d, gx, gy, gz


@njit(cache=True, **NO_REFCOUNT)
def _composite(table, v, v_lo, scale, seg_steps, gx, gy, gz, wdx, wdy, wdz, inv_spacing, shading,
               r, g, b, a):
    """Composite one approximated sample of value ``v`` standing for ``seg_steps``
    lattice steps (1 for a lattice sample); returns the accumulation and whether
    its opacity was non-zero."""
    i, f, alpha = tf_alpha(table, v, v_lo, scale)
    if alpha <= 0.0:
        return r, g, b, a, False
    if seg_steps != 1.0:
        alpha = 1.0 - (1.0 - min(alpha, 1.0)) ** seg_steps
    cr, cg, cb = tf_color(table, i, f)
    if shading[SHADING_ENABLED] != 0.0:
        cr, cg, cb = blinn_phong(cr, cg, cb, gx * inv_spacing[0], gy * inv_spacing[1], gz * inv_spacing[2],
                                 wdx, wdy, wdz, shading)
    w = (1.0 - a) * alpha
    return r + w * cr, g + w * cg, b + w * cb, a + w, True


@overload(integrate, jit_options={"cache": True, "error_model": "numpy", **NO_REFCOUNT})
def _integrate(record, scratch, state, mode, sampler, flat, nx, ny, nz, table, v_lo, scale, inv_spacing, dt, ert,
               shading, ray, wdir, t0, t1, k_next, k_min, k_max, acc):
    if record_class(record) is not BihApproxRecord:
        return None

    def impl(record, scratch, state, mode, sampler, flat, nx, ny, nz, table, v_lo, scale, inv_spacing, dt, ert,
             shading, ray, wdir, t0, t1, k_next, k_min, k_max, acc):
        ox, oy, oz, dx, dy, dz = ray
        wdx, wdy, wdz = wdir
        r, g, b, a = acc
        leaf = state[1]
        leaf_box = scratch[3]
        n_samples = 0
        n_nonempty = 0
        dc, gx, gy, gz = leaf_payload(record.tree.nodes, leaf, record.grad_scale)
        cx = 0.5 * (leaf_box[0] + leaf_box[3])
        cy = 0.5 * (leaf_box[1] + leaf_box[4])
        cz = 0.5 * (leaf_box[2] + leaf_box[5])
        d_lo = record.d_lo
        d_span = record.d_span
        if record.mode == MODE_SINGLE:
            if t1 > t0:
                tm = 0.5 * (t0 + t1)
                d = dc + gx * (ox + tm * dx - cx) + gy * (oy + tm * dy - cy) + gz * (oz + tm * dz - cz)
                r, g, b, a, hit = _composite(table, d_lo + d * d_span, v_lo, scale, (t1 - t0) / dt,
                                             gx, gy, gz, wdx, wdy, wdz, inv_spacing, shading, r, g, b, a)
                n_samples += 1
                n_nonempty += hit
            return r, g, b, a, k_next, n_samples, n_nonempty
        k0, k1 = lattice_range(t0, t1, dt)
        k = max(k0, k_next)
        k1 = min(k1, k_max)
        while k <= k1 and a < ert:
            t = k * dt
            d = dc + gx * (ox + t * dx - cx) + gy * (oy + t * dy - cy) + gz * (oz + t * dz - cz)
            r, g, b, a, hit = _composite(table, d_lo + d * d_span, v_lo, scale, 1.0,
                                         gx, gy, gz, wdx, wdy, wdz, inv_spacing, shading, r, g, b, a)
            n_samples += 1
            n_nonempty += hit
            k += 1
        return r, g, b, a, max(k_next, k), n_samples, n_nonempty

    return impl
