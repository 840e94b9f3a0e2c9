"""k-d tree traversal: a per-frame sorted leaf list (shallow), or per 8x8 tile a
frustum-culled leaf list with a per-ray stack as its fallback (deep).

Exactness. Leaves are disjoint boxes covering every occupied cell, grown by
:data:`~.build.BOX_MARGIN` so that every sample of non-zero opacity lies inside
a leaf's ray interval (see :mod:`.build`, "Exactness without the apron"). Leaves
are yielded in a visibility order (the k-d tree's: near child first, by the eye's
side of the split plane, or the ray direction's sign), so their intervals come
front to back. Each interval is widened by a tiny ``EPS`` (and clipped to the
ray's ``[t_lo, t_hi]``) so that float rounding of the ray/box clip can never drop
a sample lying on a face shared by two leaves; a widened interval only adds
lattice samples of the clip box, in order, which the naive marcher takes too. A
ray lying exactly in a split plane may see the two children's intervals
interleave; every sample of non-zero opacity in that plane lies in both children
(its cells on both sides are occupied), so either order keeps them.

Tile lists. Ray generation is affine in the pixel, so the rays of an 8x8 tile lie
in the convex hull of its four corner rays: a frustum bounded by four planes,
each through two adjacent corner rays. :func:`start_tile` walks the tree once per
tile, dropping the nodes wholly outside a plane (by more than
:data:`FRUSTUM_TOL` of the coordinates, far above the rounding of any ray of the
tile), and keeps the leaves left in visibility order; each ray then clips only
those boxes. A node dropped this way meets no ray of the tile, so every ray
meets the same leaves in the same order as its own traversal would. The order is
the per-ray rule when the four corners agree on the sign of the split axis's
direction (then every ray of the tile does), else the eye's side (perspective:
the tile's rays share one eye). :func:`start_tile` also copies the listed boxes
into rows, and each ray clips the list a run of :data:`LIST_RUN` boxes at once
(:func:`~sparsecast.kernels.ray.clip_box_list`, a loop LLVM vectorises, with the
floats of :func:`_box_interval`), moves the intervals it meets to the front in
list order (:func:`~sparsecast.kernels.ray.compact_spans`, branch-free) and reads
them one after the other before it clips the next run: a ray that terminates early
never clips the rest of a long list (mni152 at 512², 96-leaf lists: frames 15 %
less CPU than clipping the whole list in ``start_ray``). A ray parallel to an axis
clips box by box (``clip_box``'s explicit path for ``d == 0``).

Clip culling. Every sample the driver takes lies in the frame's clip box and on the
kept side of its clip planes (up to the rounding of one ray position), and a sample
of non-zero opacity lies in an occupied cell of some leaf; so a node wholly outside
the clip box, or wholly behind one plane, by more than :data:`FRUSTUM_TOL` of the
coordinates, holds no such sample and leaves the tile's list. The per-ray fallback
needs no such test: each node's interval is clipped to the ray's ``[t_lo, t_hi]``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.extending import overload

from ...kernels.borrow import NO_REFCOUNT
from ...kernels.ray import BOX_ROWS, clip_box, clip_box_list, compact_spans, inverse, slab
from ..interval import make_scratch, next_interval, record_class, start_ray, start_tile

__all__ = ["KdListRecord", "KdStackRecord", "EPS", "TILE_LEAVES", "FRUSTUM_TOL", "widen", "next_listed_leaf"]

#: relative widening of every leaf's ray interval (see the module docstring)
EPS = 1e-7
#: leaves a tile's list holds by default; a tile whose frustum meets more traverses per ray
#: (192 for the leaves of 2 cells: a list of 96 overflowed on bonsai at 512^2, 1.4x slower frames)
TILE_LEAVES = 192
#: leaves of a tile's list a ray clips at once (see ``start_ray``)
LIST_RUN = 32
#: distance tolerance of the tile frustum test, relative to the coordinates' size
FRUSTUM_TOL = 1e-6


class KdListRecord(NamedTuple):
    """The leaves of a (shallow) k-d tree in front-to-back order for one frame.

    Attributes
    ----------
    order : (nleaves,) int32
        Leaf rows front to back.
    leaf_lo, leaf_hi : (nleaves, 3) float64
        Index-space leaf boxes.
    """

    order: np.ndarray
    leaf_lo: np.ndarray
    leaf_hi: np.ndarray


class KdStackRecord(NamedTuple):
    """A (deep) k-d tree for per-ray stack traversal.

    Attributes
    ----------
    node_axis : (n,) int8
        Split axis, -1 for leaves.
    node_child : (n,) int32
        First child (the second is ``+ 1``).
    node_lo, node_hi : (n, 3) float64
        Index-space node boxes.
    stack_size : int
        Stack entries a ray can need (``2 * height + 4``).
    tile_leaves : int
        Leaves a tile's frustum-culled list may hold (:data:`TILE_LEAVES`); a tile
        whose frustum meets more, and every tile when 0, traverses per ray.
    """

    SCRATCH = True
    TILE = True

    node_axis: np.ndarray
    node_child: np.ndarray
    node_lo: np.ndarray
    node_hi: np.ndarray
    stack_size: int
    tile_leaves: int


@njit(cache=True, inline="always")
def widening(t_lo, t_hi):
    """How far :func:`widen` widens a leaf's interval on a ray whose interval is
    ``[t_lo, t_hi]`` (finite): ``EPS`` relative to it."""
    return EPS * (1.0 + abs(t_lo) + abs(t_hi))


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def widen(t_near, t_far, t_lo, t_hi):
    """Leaf interval widened by :func:`widening` and clipped to ``[t_lo, t_hi]``."""
    e = widening(t_lo, t_hi)
    return max(t_near - e, t_lo), min(t_far + e, t_hi)


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def next_listed_leaf(lst, ray, j, t_lo, t_hi):
    """From position ``j`` of the leaf list, the next leaf the ray meets:
    ``(t0, t1, j_after)``, ``t0 > t1`` when none is left."""
    ox, oy, oz, dx, dy, dz = ray
    order = lst.order
    lo = lst.leaf_lo
    hi = lst.leaf_hi
    while j < order.shape[0]:
        li = order[j]
        j += 1
        tn, tf = clip_box(ox, oy, oz, dx, dy, dz, lo[li, 0], lo[li, 1], lo[li, 2], hi[li, 0], hi[li, 1], hi[li, 2])
        t0, t1 = widen(tn, tf, t_lo, t_hi)
        if t0 <= t1:
            return t0, t1, j
    return math.inf, -math.inf, j


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # once per tile and node: a plain call
def _plane(corners, i):
    """Inward side plane ``(nx, ny, nz, px, py, pz, tol)`` of a tile frustum through
    corner rays ``i`` and ``i + 1`` (``n == 0``: no plane, a degenerate tile edge)."""
    ox, oy, oz, dx, dy, dz = corners[i]
    jx, jy, jz, ex, ey, ez = corners[(i + 1) % 4]
    kx, ky, kz, fx, fy, fz = corners[(i + 2) % 4]
    lx, ly, lz, gx, gy, gz = corners[(i + 3) % 4]
    # The plane holds both rays: through o_i, spanned by d_i and (o_j + d_j) - o_i
    # (perspective: d_i x d_j; orthographic: d x (o_j - o_i)).
    ux = jx - ox + ex
    uy = jy - oy + ey
    uz = jz - oz + ez
    nx = dy * uz - dz * uy
    ny = dz * ux - dx * uz
    nz = dx * uy - dy * ux
    # Inward: towards the two other corner rays (their points at t = 1).
    qx = 0.5 * (kx + fx + lx + gx) - ox
    qy = 0.5 * (ky + fy + ly + gy) - oy
    qz = 0.5 * (kz + fz + lz + gz) - oz
    side = nx * qx + ny * qy + nz * qz
    norm = abs(nx) + abs(ny) + abs(nz)
    scale = 1.0 + max(abs(ox), abs(oy), abs(oz))
    if not abs(side) > 1e-9 * norm * (abs(qx) + abs(qy) + abs(qz)) or norm == 0.0:
        return 0.0, 0.0, 0.0, ox, oy, oz, 0.0
    if side < 0.0:
        nx = -nx
        ny = -ny
        nz = -nz
    return nx, ny, nz, ox, oy, oz, FRUSTUM_TOL * norm * scale


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # once per tile and node: a plain call
def _far_corner(nx, ny, nz, lo, hi, n):
    """The corner of box ``n`` farthest along the direction ``(nx, ny, nz)``."""
    return (hi[n, 0] if nx > 0.0 else lo[n, 0], hi[n, 1] if ny > 0.0 else lo[n, 1],
            hi[n, 2] if nz > 0.0 else lo[n, 2])


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # once per tile and node: a plain call
def _absolute(pl, reach):
    """Plane ``pl`` of :func:`_plane` with its tolerance made absolute for boxes whose
    coordinates are at most ``reach - 1`` in magnitude: ``(nx, ny, nz, c)``, a box lying
    wholly outside when its far corner ``b`` has ``n . b < c`` (no plane: ``c = -inf``)."""
    nx, ny, nz, px, py, pz, tol = pl
    if tol == 0.0:
        return nx, ny, nz, -math.inf
    return nx, ny, nz, (nx * px + ny * py + nz * pz) - tol * reach


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # once per tile and node: a plain call
def _outside(pl, lo, hi, n):
    """Whether box ``n`` lies wholly outside the plane ``pl`` of :func:`_absolute`.

    The tolerance is the one for the tree's root box, at least each node's own (its
    coordinates are within the root's), so a node is dropped only when it lies outside by
    more than :data:`FRUSTUM_TOL` of its coordinates: one product per axis and a compare
    per node instead of that bound taken again at every node."""
    nx, ny, nz, c = pl
    bx, by, bz = _far_corner(nx, ny, nz, lo, hi, n)
    return nx * bx + ny * by + nz * bz < c


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # once per tile and node: a plain call
def _outside_clip(box, planes, tol, lo, hi, n):
    """Whether box ``n`` lies wholly outside the clip box ``box`` or behind one of
    ``planes`` (rows ``n . x >= c``), by more than ``tol`` (times a plane's 1-norm)."""
    x0, y0, z0, x1, y1, z1 = box
    if hi[n, 0] < x0 - tol or hi[n, 1] < y0 - tol or hi[n, 2] < z0 - tol \
            or lo[n, 0] > x1 + tol or lo[n, 1] > y1 + tol or lo[n, 2] > z1 + tol:
        return True
    for p in range(planes.shape[0]):
        nx = planes[p, 0]
        ny = planes[p, 1]
        nz = planes[p, 2]
        bx, by, bz = _far_corner(nx, ny, nz, lo, hi, n)  # the farthest into the kept side
        if nx * bx + ny * by + nz * bz - planes[p, 3] < -tol * (abs(nx) + abs(ny) + abs(nz)):
            return True
    return False


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def _push_children(scratch, at, c, left_first):
    """Push children ``c`` and ``c + 1`` at ``scratch[at]``, the near one last (popped first)."""
    if left_first:
        scratch[at] = c + 1
        scratch[at + 1] = c
    else:
        scratch[at] = c
        scratch[at + 1] = c + 1


@njit(cache=True, error_model="numpy", **NO_REFCOUNT)  # a plain call: see index.interval, "Inlining"
def _box_interval(ray, inv, x0, y0, z0, x1, y1, z1, t_lo, t_hi):
    """:func:`clip_box` of the box ``[x0, x1] x [y0, y1] x [z0, z1]`` with the ray's
    inverses ``inv`` (from start_ray), widened. The caller loads the box: passing the
    node arrays instead copied both array structures per call (18 words), which took
    more of the k-d tree's isosurface frame than the slab tests themselves."""
    ox, oy, oz, _, _, _ = ray
    ix, iy, iz, fx, fy, fz = inv
    tn, tf = slab(ox, ix, fx, x0, x1, -math.inf, math.inf)
    tn, tf = slab(oy, iy, fy, y0, y1, tn, tf)
    tn, tf = slab(oz, iz, fz, z0, z1, tn, tf)
    return widen(tn, tf, t_lo, t_hi)


# Once per tile, so a plain call (see index.interval, "Inlining").
@overload(start_tile, jit_options={"cache": True, **NO_REFCOUNT})
def _tile(record, scratch, corners, box, planes):
    if record_class(record) is not KdStackRecord:
        return None

    def impl(record, scratch, corners, box, planes):
        # The tile's leaves front to back, culled by its frustum: ints[0] is their
        # count (-1: more than tile_leaves, rays traverse the tree themselves),
        # ints[1:1 + tile_leaves] the leaves' nodes, the rest a stack; their boxes
        # go to the columns of `boxes` in the same order (see _scratch).
        # Order: the per-ray rule (near child by the direction's sign) when the four
        # corner rays agree on the split axis; else (perspective: one eye) the eye's
        # side, which is front to back for every ray from that eye.
        ints = scratch[0]  # indexed, not unpacked: see _start
        boxes = scratch[1]
        lo = record.node_lo
        hi = record.node_hi
        axis = record.node_axis
        child = record.node_child
        cap = record.tile_leaves
        ints[0] = 0 if cap > 0 else -1
        if axis.shape[0] == 0:
            return False  # an empty tree: no ray meets a leaf
        if cap == 0:
            return True
        # Node 0 is the root: every node's box lies within its box.
        reach = 1.0 + max(abs(lo[0, 0]), abs(lo[0, 1]), abs(lo[0, 2]), abs(hi[0, 0]), abs(hi[0, 1]), abs(hi[0, 2]))
        p0 = _absolute(_plane(corners, 0), reach)
        p1 = _absolute(_plane(corners, 1), reach)
        p2 = _absolute(_plane(corners, 2), reach)
        p3 = _absolute(_plane(corners, 3), reach)
        eye = corners[0]
        x0, y0, z0, x1, y1, z1 = box
        ctol = FRUSTUM_TOL * (1.0 + max(abs(x0), abs(y0), abs(z0), abs(x1), abs(y1), abs(z1)))
        # No clip test per node where it cannot drop one: no planes, and the clip box
        # holds the root's box (an unclipped frame; the nodes lie within the root's).
        clipping = planes.shape[0] > 0 or not (
            lo[0, 0] >= x0 - ctol and lo[0, 1] >= y0 - ctol and lo[0, 2] >= z0 - ctol
            and hi[0, 0] <= x1 + ctol and hi[0, 1] <= y1 + ctol and hi[0, 2] <= z1 + ctol)
        base = 1 + cap  # the stack, as offsets into scratch (no slice: a view per call)
        ints[base] = 0
        sp = 1
        count = 0
        while sp > 0:
            sp -= 1
            n = ints[base + sp]
            if _outside(p0, lo, hi, n) or _outside(p1, lo, hi, n) or _outside(p2, lo, hi, n) \
                    or _outside(p3, lo, hi, n) or (clipping and _outside_clip(box, planes, ctol, lo, hi, n)):
                continue
            ax = axis[n]
            if ax < 0:
                if count == cap:
                    ints[0] = -1
                    return True
                ints[1 + count] = n
                count += 1
                continue
            c = child[n]
            pos = 0
            for q in range(4):
                d = corners[q][3 + ax]
                if d >= 0.0:
                    pos += 1
            if pos == 4:
                left_first = True
            elif pos == 0:
                left_first = False
            else:
                left_first = eye[ax] <= hi[c, ax]
            _push_children(ints, base + sp, c, left_first)
            sp += 2
        ints[0] = count
        for i in range(count):
            n = ints[1 + i]
            for a in range(3):
                boxes[a, i] = lo[n, a]
                boxes[3 + a, i] = hi[n, a]
        # An empty list: the frustum meets no leaf, so no ray of the tile does.
        return count > 0

    return impl


@overload(start_ray, jit_options={"cache": True}, inline="always")
def _start(record, scratch, ray, t_lo, t_hi):
    cls = record_class(record)
    if cls is KdListRecord:
        return lambda record, scratch, ray, t_lo, t_hi: (0, t_lo, t_hi)
    if cls is KdStackRecord:

        def impl(record, scratch, ray, t_lo, t_hi):
            # List mode: position 0 of the tile's list, its intervals clipped a run at a
            # time into `spans` (stack pointer -1), or, for a ray parallel to an axis, box
            # by box (-2); stack mode (the tile's list overflowed): the root on the stack.
            # The scratch tuple is indexed, not unpacked: unpacking it here lost the
            # store of the stack's root (Numba 0.68; next_interval then read garbage).
            ints = scratch[0]
            # The ray's slab inverses, once per ray rather than once per node box
            # (the same floats :func:`clip_box` computes).
            _, _, _, dx, dy, dz = ray
            ix, fx = inverse(dx)
            iy, fy = inverse(dy)
            iz, fz = inverse(dz)
            listed = ints[0]
            sp = -1
            hits = 0
            clipped = 0
            if listed < 0:
                sp = 0
                if record.node_axis.shape[0] > 0:
                    ints[1 + record.tile_leaves] = 0
                    sp = 1
            elif fx or fy or fz:
                sp = -2
            # List mode clips nothing yet: next_interval clips the list a run at a time as
            # the ray reaches it (a ray that terminates early never clips the rest).
            return (0, sp, t_lo, t_hi, ix, iy, iz, fx, fy, fz, hits, clipped)

        return impl


@njit(cache=True)
def _stack_scratch(tile_leaves, stack_size):
    """A deep k-d tree's scratch ``(ints, boxes, spans)``: the tile's leaf count, its
    leaves and the per-ray stack; the listed leaves' boxes (rows
    :data:`~sparsecast.kernels.ray.BOX_ROWS`); one ray's interval per listed leaf
    of the run being read (rows ``t0, t1``, filled by ``start_ray`` and ``next_interval``)."""
    n = max(tile_leaves, 1)
    return (np.empty(1 + tile_leaves + stack_size, np.int32), np.empty((BOX_ROWS, n), np.float64),
            np.empty((2, min(n, LIST_RUN)), np.float64))


@overload(make_scratch, jit_options={"cache": True}, inline="always")
def _scratch(record):
    if record_class(record) is KdStackRecord:
        return lambda record: _stack_scratch(record.tile_leaves, record.stack_size)


@overload(next_interval, jit_options={"cache": True}, inline="always")
def _next(record, scratch, ray, state, t_covered):
    cls = record_class(record)
    if cls is KdListRecord:

        def impl_list(record, scratch, ray, state, t_covered):
            j, t_lo, t_hi = state
            t0, t1, j = next_listed_leaf(record, ray, j, t_lo, t_hi)
            return t0, t1, (j, t_lo, t_hi)

        return impl_list
    if cls is KdStackRecord:

        def impl_stack(record, scratch, ray, state, t_covered):
            # A child is pushed only when the ray's widened interval meets it,
            # the near child last (popped first): the left child when the ray's
            # direction on the split axis is >= 0.
            j, sp, t_lo, t_hi, ix, iy, iz, fx, fy, fz, hits, clipped = state
            inv = (ix, iy, iz, fx, fy, fz)
            ox, oy, oz, dx, dy, dz = ray
            lo = record.node_lo
            hi = record.node_hi
            ints = scratch[0]  # indexed, not unpacked: see _start
            if sp == -1:
                # The leaves of the tile's list that the ray meets, in the list's
                # visibility order: clipped and compacted a run at a time (the first
                # on the first call), so the runs come in list order too.
                spans = scratch[2]
                listed = ints[0]
                while j == hits and clipped < listed:
                    n = min(listed - clipped, LIST_RUN)
                    clip_box_list(scratch[1], clipped, n, ox, oy, oz, ix, iy, iz, widening(t_lo, t_hi), t_lo, t_hi,
                                  spans)
                    hits = compact_spans(spans, n)
                    clipped += n
                    j = 0
                if j < hits:
                    return spans[0, j], spans[1, j], (j + 1, sp, t_lo, t_hi, ix, iy, iz, fx, fy, fz, hits, clipped)
                return math.inf, -math.inf, (j, sp, t_lo, t_hi, ix, iy, iz, fx, fy, fz, hits, clipped)
            if sp < 0:
                count = ints[0]
                # The same list box by box (a ray parallel to an axis).
                while j < count:
                    n = ints[1 + j]
                    j += 1
                    t0, t1 = _box_interval(ray, inv, lo[n, 0], lo[n, 1], lo[n, 2], hi[n, 0], hi[n, 1], hi[n, 2],
                                           t_lo, t_hi)
                    if t0 <= t1:
                        return t0, t1, (j, sp, t_lo, t_hi, ix, iy, iz, fx, fy, fz, hits, clipped)
                return math.inf, -math.inf, (j, sp, t_lo, t_hi, ix, iy, iz, fx, fy, fz, hits, clipped)
            base = 1 + record.tile_leaves
            while sp > 0:
                sp -= 1
                n = ints[base + sp]
                t0, t1 = _box_interval(ray, inv, lo[n, 0], lo[n, 1], lo[n, 2], hi[n, 0], hi[n, 1], hi[n, 2],
                                       t_lo, t_hi)
                if t0 > t1:
                    continue
                ax = record.node_axis[n]
                if ax < 0:
                    return t0, t1, (j, sp, t_lo, t_hi, ix, iy, iz, fx, fy, fz, hits, clipped)
                c = record.node_child[n]
                d = dx if ax == 0 else (dy if ax == 1 else dz)
                _push_children(ints, base + sp, c, d >= 0.0)
                sp += 2
            return math.inf, -math.inf, (j, sp, t_lo, t_hi, ix, iy, iz, fx, fy, fz, hits, clipped)

        return impl_stack
