"""Ray/slab clipping and the global sampling lattice ``t_k = k * dt``.

One slab routine (:func:`slab`) serves every box test of the volume renderers:
the driver's clip, each index's node and leaf boxes. Using the same arithmetic
everywhere is what makes two indices agree bit for bit on a shared face.
"""

from __future__ import annotations

import math

from numba import njit

from .borrow import NO_REFCOUNT
from .vectorize import LaneLoopCompiler


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def slab_ordered(o, inv, flat, near, far, t0, t1):
    """Restrict ``[t0, t1]`` to one slab whose planes are given near plane first.

    ``inv = 1 / d`` (any value when ``flat``); ``near``/``far`` are the slab planes
    ordered by the ray's direction (``lo, hi`` for ``d >= 0``, ``hi, lo`` otherwise),
    so no swap is needed: callers that precompute the order per ray (the LBVH)
    save a branch per box.

    Axis-parallel rays (``flat``, i.e. ``d == 0``) are handled explicitly rather
    than through ``1/0 = inf``: with ``o`` exactly on a plane the IEEE route gives
    ``0 * inf = NaN``, which would silently drop the ray. Their planes come in
    ``lo, hi`` order.
    """
    if flat:
        if o < near or o > far:
            return 1.0, 0.0  # empty interval
        return t0, t1
    return max(t0, (near - o) * inv), min(t1, (far - o) * inv)


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def slab(o, inv, flat, lo, hi, t0, t1):
    """Restrict ``[t0, t1]`` to the slab ``lo <= o + t d <= hi`` (``inv = 1 / d``)."""
    if inv < 0.0 and not flat:
        return slab_ordered(o, inv, flat, hi, lo, t0, t1)
    return slab_ordered(o, inv, flat, lo, hi, t0, t1)


@njit(cache=True, error_model="numpy")
def inverse(d):
    """``(1 / d, d == 0)``: the per-axis values :func:`slab` takes."""
    if d == 0.0:
        return 0.0, True
    return 1.0 / d, False


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def clip_box(ox, oy, oz, dx, dy, dz, bx0, by0, bz0, bx1, by1, bz1):
    """Parametric interval ``(t_near, t_far)`` of a ray inside an axis-aligned box.

    The interval is empty (``t_near > t_far``) when the ray misses. Boxes may be
    flat (``lo == hi`` on an axis): a ray in that plane still gets an interval.
    """
    ix, fx = inverse(dx)
    iy, fy = inverse(dy)
    iz, fz = inverse(dz)
    tn, tf = slab(ox, ix, fx, bx0, bx1, -math.inf, math.inf)
    tn, tf = slab(oy, iy, fy, by0, by1, tn, tf)
    tn, tf = slab(oz, iz, fz, bz0, bz1, tn, tf)
    return tn, tf


#: rows of a :func:`clip_box_list` box array: the boxes' ``lo`` corners (x, y, z), then their ``hi``
BOX_ROWS = 6


@njit(cache=True, error_model="numpy", pipeline_class=LaneLoopCompiler, **NO_REFCOUNT)
def clip_box_list(boxes, first, count, ox, oy, oz, ix, iy, iz, pad, t_lo, t_hi, out):
    """Clip one ray against ``count`` boxes at once: what :func:`clip_box` gives each,
    widened by ``pad`` and clipped to ``[t_lo, t_hi]``, in one loop LLVM vectorises.

    A list of boxes is tested box by box with branches on the ray's direction per
    slab; for one ray those branches are the same for every box, so here they are
    taken once (the near plane's row per axis) and the loop body is straight-line
    arithmetic over contiguous rows, four or eight boxes per instruction. The floats
    are :func:`clip_box`'s: the same differences, products, ``max`` and ``min``.

    Parameters
    ----------
    boxes : (6, n) float64
        Rows ``lo_x, lo_y, lo_z, hi_x, hi_y, hi_z`` (:data:`BOX_ROWS`),
        ``n >= first + count``.
    first, count : int
        Boxes to test: columns ``first .. first + count - 1``.
    ox, oy, oz : float
        Ray origin.
    ix, iy, iz : float
        ``1 / d`` per axis (:func:`inverse`); the ray must not be parallel to an axis
        (no ``d == 0``: such rays take :func:`clip_box`'s explicit path).
    pad : float
        Widening of every interval (``t0 - pad``, ``t1 + pad``) before the clip.
    t_lo, t_hi : float
        The ray's interval.
    out : (2, m) float64
        ``out[0, i], out[1, i]``: box ``first + i``'s interval, empty (``t0 > t1``) when
        missed, ``m >= count``.
    """
    # The near and far planes' rows on each axis (slab's swap for inv < 0).
    nx, fx = (0, 3) if ix >= 0.0 else (3, 0)
    ny, fy = (1, 4) if iy >= 0.0 else (4, 1)
    nz, fz = (2, 5) if iz >= 0.0 else (5, 2)
    for i in range(count):
        b = first + i
        tn = max(max((boxes[nx, b] - ox) * ix, (boxes[ny, b] - oy) * iy), (boxes[nz, b] - oz) * iz)
        tf = min(min((boxes[fx, b] - ox) * ix, (boxes[fy, b] - oy) * iy), (boxes[fz, b] - oz) * iz)
        out[0, i] = max(tn - pad, t_lo)
        out[1, i] = min(tf + pad, t_hi)


@njit(cache=True, **NO_REFCOUNT)
def compact_spans(out, count):
    """Move the non-empty intervals among ``out[:, :count]`` (``t0 <= t1``) to its front,
    in order, and return how many there are.

    One branch-free pass after :func:`clip_box_list`: every column is stored and the
    write position advances by the comparison, so a ray's hits cost no mispredicted
    branch each, where scanning the list for them later took one per hit.
    """
    m = 0
    for i in range(count):
        t0 = out[0, i]
        t1 = out[1, i]
        out[0, m] = t0
        out[1, m] = t1
        m += 1 if t0 <= t1 else 0
    return m


@njit(cache=True, **NO_REFCOUNT)
def lattice_range(t_near, t_far, dt):
    """Indices ``k0..k1`` (inclusive) of lattice samples ``k * dt`` in ``[t_near, t_far]``.

    Samples behind the eye (``t < 0``) are never taken. Returns ``k1 < k0`` when
    no sample lies in the interval.
    """
    if t_near < 0.0:
        t_near = 0.0
    if t_far < t_near:
        return 1, 0
    k0 = math.ceil(t_near / dt)
    k1 = math.floor(t_far / dt)
    return k0, k1


@njit(cache=True, inline="always")
def _k_from_near(t, dt, open_face):
    """Smallest ``k`` a near face at ``t`` admits (``t > 0``): ``k dt >= t``, or ``>`` if open."""
    q = t / dt
    if open_face:
        return int(math.floor(q)) + 1
    return int(math.ceil(q))


@njit(cache=True, inline="always")
def _k_from_far(t, dt, open_face):
    """Largest ``k`` a far face at ``t`` admits (``t >= 0``): ``k dt <= t``, or ``<`` if open."""
    q = t / dt
    if open_face:
        return int(math.ceil(q)) - 1
    return int(math.floor(q))


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # once per ray or tile, a plain call: see index.interval, "Inlining"
def clip_lattice(ox, oy, oz, dx, dy, dz, x0, y0, z0, x1, y1, z1, ox0, oy0, oz0, ox1, oy1, oz1, any_open, dt):
    """Lattice samples of a ray inside a box whose faces may be half-open.

    Parameters
    ----------
    ox, oy, oz, dx, dy, dz : float
        Index-space ray origin and direction.
    x0, y0, z0, x1, y1, z1 : float
        Box corners.
    ox0, oy0, oz0, ox1, oy1, oz1 : bool
        Open faces (lower x, y, z; upper x, y, z): a sample exactly on an open
        face is outside. Two boxes that share a face, one with it open, the other
        with it closed, therefore never both take a sample on it (each decides
        from the same ``(plane - o) / d``, with complementary rules).
    any_open : bool
        Whether any face is open (all closed: the fast path, one slab pass).
    dt : float
        Lattice step.

    Returns
    -------
    k_lo, k_hi : int
        Inclusive range of lattice indices inside the box (``k_lo > k_hi``: none).
        ``k >= 0`` always (no sample behind the eye).
    t_lo, t_hi : float
        The ray's interval in the closed box, ``t_lo >= 0``.

    Notes
    -----
    Each face bounds ``k`` on its own and the bounds are intersected. With every
    face closed this is ``lattice_range`` of the box's ``clip_box`` interval:
    ``ceil`` and ``floor`` are monotone, so the bound of the limiting face is the
    bound of the interval. Scalars only: no array in the per-ray path.
    """
    ix, fx = inverse(dx)
    iy, fy = inverse(dy)
    iz, fz = inverse(dz)
    t_lo, t_hi = slab(ox, ix, fx, x0, x1, 0.0, math.inf)
    t_lo, t_hi = slab(oy, iy, fy, y0, y1, t_lo, t_hi)
    t_lo, t_hi = slab(oz, iz, fz, z0, z1, t_lo, t_hi)
    if t_lo > t_hi:
        return 1, 0, t_lo, t_hi
    k_lo = int(math.ceil(t_lo / dt))
    k_hi = int(math.floor(t_hi / dt))
    if any_open:
        k_lo, k_hi = _open_face(ox, ix, fx, x0, x1, ox0, ox1, dt, t_lo, t_hi, k_lo, k_hi)
        k_lo, k_hi = _open_face(oy, iy, fy, y0, y1, oy0, oy1, dt, t_lo, t_hi, k_lo, k_hi)
        k_lo, k_hi = _open_face(oz, iz, fz, z0, z1, oz0, oz1, dt, t_lo, t_hi, k_lo, k_hi)
    return k_lo, k_hi, t_lo, t_hi


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # once per ray or tile, a plain call: see index.interval, "Inlining"
def clip_planes(ox, oy, oz, dx, dy, dz, planes, dt, t_lo, t_hi, k_lo, k_hi):
    """Restrict a ray's interval and lattice range to the half-spaces of ``planes``.

    Parameters
    ----------
    ox, oy, oz, dx, dy, dz : float
        Index-space ray.
    planes : (m, 4) float64
        Index-space half-spaces ``n . x >= c`` as rows ``(nx, ny, nz, c)``.
    dt, t_lo, t_hi, k_lo, k_hi
        The step and what :func:`clip_lattice` returned.

    Returns
    -------
    k_lo, k_hi, t_lo, t_hi
        Narrowed (``k_lo > k_hi``: no sample left). A lattice sample is kept iff its
        ``t`` passes every plane's bound, ``ceil`` / ``floor`` of ``t / dt`` as for
        a closed box face.
    entered : int
        The plane the ray enters the region through (the one that set ``t_lo``),
        or -1 when ``t_lo`` is the box's: what a clip cap is lit by (:func:`entry_face`).
    """
    entered = -1
    for p in range(planes.shape[0]):
        nd = planes[p, 0] * dx + planes[p, 1] * dy + planes[p, 2] * dz
        f0 = planes[p, 0] * ox + planes[p, 1] * oy + planes[p, 2] * oz - planes[p, 3]
        if nd == 0.0:
            if f0 < 0.0:
                return 1, 0, t_lo, t_hi, entered  # parallel and outside
            continue
        t = -f0 / nd
        if nd > 0.0:  # entering the half-space at t
            if t > t_lo:
                t_lo = t
                entered = p
                if t_lo > t_hi:
                    return 1, 0, t_lo, t_hi, entered
                k_lo = max(k_lo, int(math.ceil(t / dt)))
        elif t < t_hi:  # leaving it at t
            t_hi = t
            if t_lo > t_hi:
                return 1, 0, t_lo, t_hi, entered
            k_hi = min(k_hi, int(math.floor(t / dt)))
    return k_lo, k_hi, t_lo, t_hi, entered


@njit(cache=True, inline="always")
def _near_face(o, d, lo, hi, cut_lo, cut_hi, t_lo):
    """Whether the near face of one slab is a cut face the ray enters through at ``t_lo``.

    The near face's ``t`` is computed as :func:`slab` computes it (``(plane - o) * (1 / d)``),
    so it equals ``t_lo`` bit for bit exactly when this face bounded the interval.
    """
    if d == 0.0:
        return False
    inv = 1.0 / d
    if inv < 0.0:
        return cut_hi and (hi - o) * inv == t_lo
    return cut_lo and (lo - o) * inv == t_lo


@njit(cache=True, **NO_REFCOUNT)
def entry_face(ox, oy, oz, dx, dy, dz, x0, y0, z0, x1, y1, z1, cut_lo, cut_hi, planes, entered, t_lo):
    """The cut face a ray enters its clipped interval through, for capping.

    Parameters
    ----------
    ox, oy, oz, dx, dy, dz : float
        Index-space ray.
    x0, y0, z0, x1, y1, z1 : float
        The clip box (as given to :func:`clip_lattice`).
    cut_lo, cut_hi : (3,) bool
        Box faces that cut the volume (lie strictly inside its box); the others are
        the volume's own faces, which are not capped.
    planes : (m, 4) float64
        Clip half-spaces (as given to :func:`clip_planes`).
    entered : int
        The plane :func:`clip_planes` reported (-1: none).
    t_lo : float
        The interval's start after the box and the planes.

    Returns
    -------
    found : bool
        Whether ``t_lo`` is where the ray crosses a clip plane or a cut face of the
        box (not the eye, ``t_lo = 0`` inside the region, nor a face of the volume).
    gx, gy, gz : float
        The face's index-space normal (unnormalised; a plane's row ``n``), which times
        ``1 / spacing`` is its world normal, like a gradient. A ray through an edge of
        the box takes the last axis whose face attains ``t_lo``.

    Notes
    -----
    A box face's ``t`` is recomputed as :func:`slab` computed it (one subtraction and
    one product, which no contraction can change), so the test is an exact float
    comparison; the plane comes from the clipping itself. The face is chosen before
    any traversal, so every index caps the same rays.
    """
    if entered >= 0:
        return True, planes[entered, 0], planes[entered, 1], planes[entered, 2]
    found = False
    gx = 0.0
    gy = 0.0
    gz = 0.0
    if _near_face(ox, dx, x0, x1, cut_lo[0], cut_hi[0], t_lo):
        found = True
        gx, gy, gz = 1.0, 0.0, 0.0
    if _near_face(oy, dy, y0, y1, cut_lo[1], cut_hi[1], t_lo):
        found = True
        gx, gy, gz = 0.0, 1.0, 0.0
    if _near_face(oz, dz, z0, z1, cut_lo[2], cut_hi[2], t_lo):
        found = True
        gx, gy, gz = 0.0, 0.0, 1.0
    return found, gx, gy, gz


@njit(cache=True, **NO_REFCOUNT)
def _open_face(o, inv, flat, lo, hi, open_lo, open_hi, dt, t_lo, t_hi, k_lo, k_hi):
    """Tighten ``[k_lo, k_hi]`` by one axis's open faces (see :func:`clip_lattice`)."""
    if flat:
        if (open_lo and o == lo) or (open_hi and o == hi):
            return 1, 0
        return k_lo, k_hi
    if not (open_lo or open_hi):
        return k_lo, k_hi
    t_a = (lo - o) * inv
    t_b = (hi - o) * inv
    o_a = open_lo
    o_b = open_hi
    if inv < 0.0:
        t_a, t_b = t_b, t_a
        o_a, o_b = o_b, o_a
    # A face more than one step outside the interval cannot tighten its bound
    # (ceil / floor are monotone); skipping it also keeps ``int()`` away from the
    # huge t of nearly parallel axes.
    if o_a and t_a >= 0.0 and t_a >= t_lo - dt:
        k_lo = max(k_lo, _k_from_near(t_a, dt, True))
    if o_b and t_b <= t_hi + dt:
        k_hi = min(k_hi, _k_from_far(t_b, dt, True))
    return k_lo, k_hi
