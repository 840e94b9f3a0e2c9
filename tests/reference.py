"""A slow, pure-NumPy reference DVR: the test oracle for every renderer.

Written from the contract in DESIGN.md, independently of ``sparsecast.kernels`` and
``sparsecast.render`` (it imports neither). It uses only the public data objects:
``Camera.rays`` for the primary rays, ``TransferFunction.opacity_table`` /
``value_range`` / ``scale`` / ``unit_distance`` for classification, and the
``Volume`` attributes (``data``, ``spacing``, ``origin``).

Contract implemented (unshaded only; gradient shading is not modelled):

* World ray ``o + t d`` with ``|d| = 1``; in index space ``p(t) = (o - origin) / spacing
  + t * d / spacing``, so ``t`` stays a world-space distance.
* Domain box ``[0, nx-1] x [0, ny-1] x [0, nz-1]``; ``[t_near, t_far]`` is the ray-box
  interval (slab test). An axis-parallel ray (``d_axis == 0``) whose origin lies outside
  that slab misses; one whose origin lies on or inside it keeps its interval.
* Samples at ``t_k = k * dt`` for every integer ``k`` with ``t_k >= 0`` and
  ``t_near <= t_k <= t_far``.
* Trilinear interpolation with coordinates clamped to the box; vertex-centred voxels,
  ``data[k, j, i]`` is the value at point ``(i, j, k)``. Label TFs
  (``tf.sampling == "nearest"``) read the nearest voxel, ``floor(c + 0.5)`` per axis;
  smooth label TFs (``"smooth-labels"``) classify each of the eight corners of the
  cell and blend their table RGBA, premultiplied, with the trilinear weights
  (:func:`smooth_labels`).
* TF lookup ``x = clamp((v - lo) * scale, 0, n-1)``, ``i = min(floor(x), n-2)``, linear
  blend of rows ``i`` and ``i+1`` of ``tf.opacity_table(dt, unit)`` with
  ``unit = tf.unit_distance or min(spacing)``.
* Front-to-back premultiplied compositing of samples with ``alpha > 0``:
  ``w = (1 - A) a; C += w rgb; A += w``; before each sample stop if ``A >= ert``.
* Background (straight RGBA) composited last: ``C += (1 - A) ba bg_rgb; A += (1 - A) ba``.

Floating-point notes. Whether a lattice point exactly on the box boundary is taken
depends on the last bit of ``t_near`` / ``t_far``. So that sample counts can be
compared *exactly*, the reference evaluates those quantities with the same sequence
of IEEE operations the contract's natural implementation uses: division by the
spacing is done as multiplication by ``1 / spacing`` and the slab test divides as
``(lo - o) * (1 / d)``. All arithmetic is float64; the image is returned as float32.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "reference_render",
    "ray_box",
    "lattice",
    "trilinear",
    "tf_lookup",
    "smooth_labels",
    "BACKGROUNDS",
]

BACKGROUNDS = {
    "transparent": (0.0, 0.0, 0.0, 0.0),
    "black": (0.0, 0.0, 0.0, 1.0),
    "white": (1.0, 1.0, 1.0, 1.0),
    "gray": (0.5, 0.5, 0.5, 1.0),
}


def ray_box(o: np.ndarray, d: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ray/box interval of index-space rays against the box ``[0, hi]``.

    ``o`` and ``d`` have shape (N, 3). Returns ``(t_near, t_far)``; a miss has
    ``t_near > t_far``.
    """
    n = o.shape[0]
    t_near = np.full(n, -np.inf)
    t_far = np.full(n, np.inf)
    for axis in range(3):
        oa, da = o[:, axis], d[:, axis]
        lo_a, hi_a = 0.0, float(hi[axis])
        par = da == 0.0
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            inv = 1.0 / np.where(par, 1.0, da)
            t0 = (lo_a - oa) * inv
            t1 = (hi_a - oa) * inv
        ta = np.minimum(t0, t1)
        tb = np.maximum(t0, t1)
        # Axis-parallel rays: the slab constrains nothing if the origin is inside
        # it (boundary included) and empties the interval otherwise.
        outside = par & ((oa < lo_a) | (oa > hi_a))
        ta = np.where(par, -np.inf, ta)
        tb = np.where(par, np.inf, tb)
        t_near = np.maximum(t_near, ta)
        t_far = np.minimum(t_far, tb)
        t_near = np.where(outside, 1.0, t_near)
        t_far = np.where(outside, 0.0, t_far)
    return t_near, t_far


def lattice(t_near: np.ndarray, t_far: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Inclusive lattice index ranges ``k0..k1`` of ``k * dt`` in ``[max(t_near, 0), t_far]``.

    Empty ranges come back as ``k0 = 1, k1 = 0``.
    """
    tn = np.maximum(t_near, 0.0)
    miss = ~(t_far >= tn)
    with np.errstate(invalid="ignore", over="ignore"):
        k0 = np.ceil(np.where(miss, dt, tn) / dt)
        k1 = np.floor(np.where(miss, 0.0, t_far) / dt)
    k0 = np.where(miss, 1, k0).astype(np.int64)
    k1 = np.where(miss, 0, k1).astype(np.int64)
    return k0, k1


def _axis(x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clamp index coordinate to [0, n-1]; lower/upper voxel and fraction."""
    x = np.clip(x, 0.0, float(n - 1))
    if n >= 2:
        i0 = np.minimum(np.floor(x).astype(np.int64), n - 2)
        i1 = i0 + 1
    else:
        i0 = np.zeros(x.shape, np.int64)
        i1 = i0
    return i0, i1, x - i0


def trilinear(data: np.ndarray, x, y, z) -> np.ndarray:
    """Trilinear interpolation of ``data[k, j, i]`` at index points ``(x, y, z)`` (clamped)."""
    nz, ny, nx = data.shape
    x, y, z = (np.asarray(c, np.float64) for c in (x, y, z))
    i0, i1, fx = _axis(x, nx)
    j0, j1, fy = _axis(y, ny)
    k0, k1, fz = _axis(z, nz)

    def at(k, j, i):
        return data[k, j, i].astype(np.float64)

    v000, v001 = at(k0, j0, i0), at(k0, j0, i1)
    v010, v011 = at(k0, j1, i0), at(k0, j1, i1)
    v100, v101 = at(k1, j0, i0), at(k1, j0, i1)
    v110, v111 = at(k1, j1, i0), at(k1, j1, i1)
    # x first, then y, then z
    c00 = v000 + fx * (v001 - v000)
    c10 = v010 + fx * (v011 - v010)
    c01 = v100 + fx * (v101 - v100)
    c11 = v110 + fx * (v111 - v110)
    c0 = c00 + fy * (c10 - c00)
    c1 = c01 + fy * (c11 - c01)
    return c0 + fz * (c1 - c0)


def nearest(data: np.ndarray, x, y, z) -> np.ndarray:
    """Value of the voxel nearest to index points ``(x, y, z)``: ``floor(c + 0.5)`` clamped
    to the box (ties round up), for label TFs (``tf.sampling == "nearest"``)."""
    nz, ny, nx = data.shape
    idx = [np.clip(np.floor(np.asarray(c, np.float64) + 0.5), 0, n - 1).astype(np.int64)
           for c, n in ((x, nx), (y, ny), (z, nz))]
    return data[idx[2], idx[1], idx[0]].astype(np.float64)


def smooth_labels(data: np.ndarray, table: np.ndarray, v_lo: float, scale: float, x, y, z) -> np.ndarray:
    """Straight RGBA of smooth label boundaries at index points ``(x, y, z)``: each label's
    weight is the sum of the trilinear weights of the cell corners holding it; opacity
    is ``sum_l w_l a_l`` and colour ``sum_l w_l a_l rgb_l / opacity`` (0 where empty)."""
    nz, ny, nx = data.shape
    x, y, z = (np.asarray(c, np.float64) for c in (x, y, z))
    cells = [_axis(c, n) for c, n in ((x, nx), (y, ny), (z, nz))]
    (i0, i1, fx), (j0, j1, fy), (k0, k1, fz) = cells
    ids = data.astype(np.float64)
    corner = [(ids[kk, jj, ii], wx * wy * wz)
              for kk, wz in ((k0, 1.0 - fz), (k1, fz))
              for jj, wy in ((j0, 1.0 - fy), (j1, fy))
              for ii, wx in ((i0, 1.0 - fx), (i1, fx))]
    labels = np.unique(np.concatenate([v.ravel() for v, _ in corner]))
    weight = {label: sum(np.where(v == label, w, 0.0) for v, w in corner) for label in labels}
    premult = np.zeros(x.shape + (4,))
    for label, w in weight.items():
        rgba = tf_lookup(table, np.array([label]), v_lo, scale)[0]
        premult[..., :3] += (w * rgba[3])[..., None] * rgba[:3]
        premult[..., 3] += w * rgba[3]
    out = premult.copy()
    on = premult[..., 3] > 0
    out[on, :3] = premult[on, :3] / premult[on, 3:4]
    return out


def tf_lookup(table: np.ndarray, v: np.ndarray, v_lo: float, scale: float) -> np.ndarray:
    """RGBA (straight colour, table opacity) at values ``v``; shape ``v.shape + (4,)``."""
    n = table.shape[0]
    x = np.clip((np.asarray(v, np.float64) - v_lo) * scale, 0.0, float(n - 1))
    i = np.minimum(np.floor(x).astype(np.int64), n - 2)
    f = (x - i)[..., None]
    g = 1.0 - f
    t = table.astype(np.float64)
    return g * t[i] + f * t[i + 1]


def _background(background) -> np.ndarray:
    if isinstance(background, str):
        return np.array(BACKGROUNDS[background.lower()], np.float64)
    bg = np.asarray(background, np.float64).ravel()
    if bg.size == 3:
        bg = np.append(bg, 1.0)
    assert bg.shape == (4,)
    return bg


def reference_render(
    volume,
    tf,
    camera,
    width: int,
    height: int,
    *,
    dt: float | None = None,
    ert: float = 0.99,
    background="transparent",
) -> tuple[np.ndarray, np.ndarray]:
    """Render like ``sparsecast.render(..., index='naive', shading=False)``.

    Returns
    -------
    rgba : (H, W, 4) float32
        Premultiplied colour and opacity, background composited.
    samples : (H, W) int64
        Lattice samples taken per pixel (before early termination stopped the ray).
    """
    spacing = np.asarray(volume.spacing, np.float64)
    origin = np.asarray(volume.origin, np.float64)
    data = np.asarray(volume.data)
    nz, ny, nx = data.shape
    if dt is None:
        dt = 0.5 * float(spacing.min())
    dt = float(dt)
    unit = tf.unit_distance if tf.unit_distance is not None else float(spacing.min())
    table = np.asarray(tf.opacity_table(dt, unit), np.float32)
    v_lo = float(tf.value_range[0])
    scale = float(tf.scale)
    bg = _background(background)
    sampling = getattr(tf, "sampling", "trilinear")
    if sampling == "smooth-labels":
        def classify(p):
            return smooth_labels(data, table, v_lo, scale, p[:, 0], p[:, 1], p[:, 2])
    else:
        sample = {"trilinear": trilinear, "nearest": nearest}[sampling]

        def classify(p):
            return tf_lookup(table, sample(data, p[:, 0], p[:, 1], p[:, 2]), v_lo, scale)

    wo, wd = camera.rays(width, height)
    wo = wo.reshape(-1, 3).astype(np.float64)
    wd = wd.reshape(-1, 3).astype(np.float64)
    inv_spacing = 1.0 / spacing
    o = (wo - origin) * inv_spacing
    d = wd * inv_spacing
    box_hi = np.array([nx - 1.0, ny - 1.0, nz - 1.0])
    t_near, t_far = ray_box(o, d, box_hi)
    k0, k1 = lattice(t_near, t_far, dt)

    nrays = o.shape[0]
    acc = np.zeros((nrays, 4), np.float64)  # premultiplied r, g, b, alpha
    samples = np.zeros(nrays, np.int64)
    hit = k1 >= k0
    if hit.any():
        kmin = int(k0[hit].min())
        kmax = int(k1[hit].max())
        live = np.flatnonzero(hit)
        for k in range(kmin, kmax + 1):
            sel = live[(k0[live] <= k) & (k1[live] >= k) & (acc[live, 3] < ert)]
            # Rays that are past their interval or terminated never come back.
            live = live[(k1[live] >= k + 1) & (acc[live, 3] < ert)]
            if sel.size == 0:
                if live.size == 0:
                    break
                continue
            t = k * dt
            p = o[sel] + t * d[sel]
            rgba = classify(p)
            samples[sel] += 1
            a = rgba[:, 3]
            on = a > 0.0
            if not on.any():
                continue
            idx = sel[on]
            w = (1.0 - acc[idx, 3]) * a[on]
            acc[idx, 0] += w * rgba[on, 0]
            acc[idx, 1] += w * rgba[on, 1]
            acc[idx, 2] += w * rgba[on, 2]
            acc[idx, 3] += w

    rest = (1.0 - acc[:, 3]) * bg[3]
    out = np.empty((nrays, 4), np.float64)
    out[:, :3] = acc[:, :3] + rest[:, None] * bg[:3]
    out[:, 3] = acc[:, 3] + rest
    return out.reshape(height, width, 4).astype(np.float32), samples.reshape(height, width)


def expected_sample_count(t_near: float, t_far: float, dt: float) -> int:
    """Number of lattice points ``k * dt`` in ``[max(t_near, 0), t_far]`` (scalar helper)."""
    tn = max(t_near, 0.0)
    if t_far < tn:
        return 0
    return max(0, math.floor(t_far / dt) - math.ceil(tn / dt) + 1)


def reference_iso(
    volume, tf, camera, width: int, height: int, values, colors=None, *, dt: float | None = None,
    ert: float = 0.99, dvr: bool = False, steps: int = 5,
) -> np.ndarray:
    """Render like ``sparsecast.render(..., index='naive', mode='iso' (or 'iso+dvr'), shading=False)``.

    Contract: lattice samples ``f_k`` as in :func:`reference_render`; a surface ``v``
    lies between samples ``k-1`` and ``k`` (both inside the ray's box interval) when
    ``f_{k-1} >= v`` and ``f_k >= v`` differ; its ``t`` is found by ``steps`` bisections
    of ``[t_{k-1}, t_k]`` and a secant step; surfaces between ``k-1`` and ``k`` are
    composited in order of ``t`` (ties by isovalue index) with straight colour and
    opacity ``colors[j]``, then (``dvr``) the DVR sample ``k``; early termination
    before each surface and sample. ``colors`` defaults to the TF colour, opaque.
    Written per ray in plain Python (slow; small images only).
    """
    spacing = np.asarray(volume.spacing, np.float64)
    origin = np.asarray(volume.origin, np.float64)
    data = np.asarray(volume.data)
    nz, ny, nx = data.shape
    dt = 0.5 * float(spacing.min()) if dt is None else float(dt)
    values = np.atleast_1d(np.asarray(values, np.float64))
    if colors is None:
        colors = np.ones((len(values), 4))
        colors[:, :3] = tf(values)[:, :3]
    colors = np.asarray(colors, np.float64)
    unit = tf.unit_distance if tf.unit_distance is not None else float(spacing.min())
    table = np.asarray(tf.opacity_table(dt, unit), np.float32)
    wo, wd = camera.rays(width, height)
    o = (wo.reshape(-1, 3) - origin) / spacing
    d = wd.reshape(-1, 3) / spacing
    t_near, t_far = ray_box(o, d, np.array([nx - 1.0, ny - 1.0, nz - 1.0]))
    k0, k1 = lattice(t_near, t_far, dt)
    out = np.zeros((o.shape[0], 4))

    def field(i, t):
        p = o[i] + t * d[i]
        return float(trilinear(data, p[0:1], p[1:2], p[2:3])[0])

    def refine(i, ta, tb, ga, gb, v):
        above = ga >= 0.0
        for _ in range(steps):
            tm = 0.5 * (ta + tb)
            gm = field(i, tm) - v
            if (gm >= 0.0) == above:
                ta, ga = tm, gm
            else:
                tb, gb = tm, gm
        return tb if ga == gb else ta + (tb - ta) * (ga / (ga - gb))

    for i in range(o.shape[0]):
        acc = np.zeros(4)
        f_prev = None
        for k in range(int(k0[i]), int(k1[i]) + 1):
            if acc[3] >= ert:
                break
            f = field(i, k * dt)
            if f_prev is not None:
                hits = sorted((refine(i, (k - 1) * dt, k * dt, f_prev - v, f - v, v), j)
                              for j, v in enumerate(values) if (f_prev >= v) != (f >= v))
                for _, j in hits:
                    if acc[3] >= ert:
                        break
                    w = (1.0 - acc[3]) * colors[j, 3]
                    acc[:3] += w * colors[j, :3]
                    acc[3] += w
            if dvr and acc[3] < ert:
                rgba = tf_lookup(table, np.array([f]), float(tf.value_range[0]), float(tf.scale))[0]
                if rgba[3] > 0:
                    w = (1.0 - acc[3]) * rgba[3]
                    acc[:3] += w * rgba[:3]
                    acc[3] += w
            f_prev = f
        out[i] = acc
    return out.reshape(height, width, 4).astype(np.float32)
