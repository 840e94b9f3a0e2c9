"""Spatial splits before the build: triangle references with tighter boxes (Karras & Aila 2013).

A long or slanted triangle has a box much larger than itself; every ray that enters
the box tests the triangle, and the SAH cannot separate it from its neighbours.
Spatial splits (SBVH, Stich et al. 2009) cut such triangles' boxes while building;
*pre-splitting* (Ernst & Greiner 2007; Karras & Aila, "Fast Parallel Construction
of High-Quality Bounding Volume Hierarchies", HPG 2013, section 4.1) cuts them once
before an unchanged binned-SAH build, so the parallel builder of :mod:`.sah` keeps
working on plain box references, and a triangle then lies in the leaves of several
references: the traversal tests it more than once, which changes no hit.

The rule, as Karras & Aila's:

1. Split planes lie on a dyadic grid over the mesh's box: on each axis, level ``l``
   holds the planes at multiples of ``extent / 2^l``. The top levels are the planes
   an SAH build of the whole mesh tends to cut at, so splitting there separates the
   triangle from the subtrees it would straddle. The *importance* of a box is the
   coarsest level with a plane strictly inside it (any axis).
2. Each triangle's priority is ``(2^-l (A_box - A_ideal))^(1/3)``: ``l`` its box's
   importance, ``A_box`` its box's half area and ``A_ideal`` what the half areas of
   its pieces' boxes tend to when it is cut very finely (its area times the 1-norm
   of its unit normal). ``budget * m`` extra references go to the triangles in
   proportion to their priorities.
3. A triangle given ``s > 1`` references is cut at the most important plane of its
   box; each side's box is the box of the part of the triangle in it (the triangle
   clipped to the side's box), and the ``s`` references go to the two sides in
   proportion to their boxes' longest extents, recursively.

Exactness: the parts of a triangle cover it, and each part lies in its reference's
box (computed in float64, rounded outwards to float32 and kept within the parent's
box, which holds the part), so a ray's hit on the triangle lies in the box of some
reference and the traversal finds it; a hit found twice is the same ``t``.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["presplit_refs", "MAX_LEVEL", "MAX_REFS"]

#: finest grid level searched for a split plane
MAX_LEVEL = 24
#: most references one triangle gets
MAX_REFS = 64
#: vertices a triangle clipped by a box can have (3 + one per plane)
_MAX_POLY = 9


@njit(cache=True, inline="always")
def _importance(lo, hi, s_lo, inv_ext):
    """``(level, axis, plane)``: the coarsest grid plane strictly inside ``[lo, hi]``
    (the widest axis first on a tie), or level ``MAX_LEVEL + 1`` when none."""
    best_l = MAX_LEVEL + 1
    best_a = -1
    best_p = 0.0
    best_w = -1.0
    for a in range(3):
        if inv_ext[a] == 0.0 or not hi[a] > lo[a]:
            continue
        u0 = (lo[a] - s_lo[a]) * inv_ext[a]
        u1 = (hi[a] - s_lo[a]) * inv_ext[a]
        w = u1 - u0
        for lev in range(1, MAX_LEVEL + 1):
            if lev > best_l or (lev == best_l and w <= best_w):
                break
            cells = float(1 << lev)
            k = np.floor(u1 * cells)
            if k == u1 * cells:
                k -= 1.0  # a plane on the box's top face is not inside it
            if k / cells > u0 and k >= 1.0:
                best_l = lev
                best_a = a
                best_p = s_lo[a] + (k / cells) / inv_ext[a]
                best_w = w
                break
    return best_l, best_a, best_p


@njit(cache=True, inline="always")
def _clip_axis(px, py, pz, n, out_x, out_y, out_z, a, c, keep_below):
    """Sutherland-Hodgman: the polygon ``p[:n]`` clipped to ``x_a <= c`` (or ``>= c``);
    vertices on the plane get the coordinate ``c`` exactly. Returns the new count."""
    m = 0
    for i in range(n):
        j = (i + 1) % n
        vi = px[i] if a == 0 else (py[i] if a == 1 else pz[i])
        vj = px[j] if a == 0 else (py[j] if a == 1 else pz[j])
        ini = vi <= c if keep_below else vi >= c
        inj = vj <= c if keep_below else vj >= c
        if ini:
            out_x[m] = px[i]
            out_y[m] = py[i]
            out_z[m] = pz[i]
            m += 1
        if ini != inj:
            f = (c - vi) / (vj - vi)
            out_x[m] = px[i] + f * (px[j] - px[i])
            out_y[m] = py[i] + f * (py[j] - py[i])
            out_z[m] = pz[i] + f * (pz[j] - pz[i])
            if a == 0:
                out_x[m] = c
            elif a == 1:
                out_y[m] = c
            else:
                out_z[m] = c
            m += 1
    return m


@njit(cache=True)
def _part_box(tri, lo, hi, cap_lo, cap_hi, out_lo, out_hi, bx, by, bz, cx, cy, cz):
    """The box of the part of triangle ``tri`` (3, 3) inside ``[lo, hi]``, rounded outwards
    to float32 and kept within ``[cap_lo, cap_hi]`` (a float32 box holding the part: the
    parent's; not ``[lo, hi]``, whose split plane need not be a float32, so that capping
    at it and rounding could cut a strip off the part); returns False when it is empty."""
    n = 3
    for v in range(3):
        bx[v] = tri[v, 0]
        by[v] = tri[v, 1]
        bz[v] = tri[v, 2]
    for a in range(3):
        n = _clip_axis(bx, by, bz, n, cx, cy, cz, a, lo[a], False)
        n = _clip_axis(cx, cy, cz, n, bx, by, bz, a, hi[a], True)
        if n == 0:
            return False
    for a in range(3):
        out_lo[a] = np.inf
        out_hi[a] = -np.inf
    for i in range(n):
        out_lo[0] = min(out_lo[0], bx[i])
        out_hi[0] = max(out_hi[0], bx[i])
        out_lo[1] = min(out_lo[1], by[i])
        out_hi[1] = max(out_hi[1], by[i])
        out_lo[2] = min(out_lo[2], bz[i])
        out_hi[2] = max(out_hi[2], bz[i])
    for a in range(3):
        # One float32 step outwards covers the float64 rounding of the clipped vertices.
        l32 = np.nextafter(np.float32(out_lo[a]), np.float32(-np.inf))
        h32 = np.nextafter(np.float32(out_hi[a]), np.float32(np.inf))
        out_lo[a] = max(float(l32), cap_lo[a])
        out_hi[a] = min(float(h32), cap_hi[a])
    return True


@njit(cache=True, parallel=True)
def _priorities(tris, blo, bhi, s_lo, inv_ext):
    m = tris.shape[0]
    pri = np.zeros(m, np.float64)
    for t in prange(m):
        lo = blo[t]
        hi = bhi[t]
        lev, a, _ = _importance(lo, hi, s_lo, inv_ext)
        if a < 0:
            continue
        ex = hi[0] - lo[0]
        ey = hi[1] - lo[1]
        ez = hi[2] - lo[2]
        a_box = ex * ey + ey * ez + ez * ex
        e1 = tris[t, 1] - tris[t, 0]
        e2 = tris[t, 2] - tris[t, 0]
        nx = e1[1] * e2[2] - e1[2] * e2[1]
        ny = e1[2] * e2[0] - e1[0] * e2[2]
        nz = e1[0] * e2[1] - e1[1] * e2[0]
        a_ideal = 0.5 * (abs(nx) + abs(ny) + abs(nz))  # area times the normal's 1-norm
        excess = a_box - a_ideal
        if excess > 0.0:
            pri[t] = (excess * 2.0 ** (-lev)) ** (1.0 / 3.0)
    return pri


@njit(cache=True)
def _emit(out_lo, out_hi, out_id, w, lo, hi, t):
    for a in range(3):
        out_lo[w, a] = lo[a]
        out_hi[w, a] = hi[a]
    out_id[w] = t


@njit(cache=True, parallel=True)
def _split_all(tris, blo, bhi, refs, offset, s_lo, inv_ext, out_lo, out_hi, out_id):
    """Write triangle ``t``'s ``refs[t]`` references at ``offset[t]`` (see the module
    docstring); slots a triangle does not fill get the id -1."""
    m = tris.shape[0]
    chunk = 1024
    depth = MAX_REFS + 2  # a split pops one box and pushes two: at most one more per reference
    for ci in prange((m + chunk - 1) // chunk):
        # Scratch once per chunk: the kernel allocates nothing per triangle.
        tri = np.empty((3, 3))
        st_lo = np.empty((depth, 3))
        st_hi = np.empty((depth, 3))
        st_n = np.empty(depth, np.int64)
        bx = np.empty(_MAX_POLY)
        by = np.empty(_MAX_POLY)
        bz = np.empty(_MAX_POLY)
        cx = np.empty(_MAX_POLY)
        cy = np.empty(_MAX_POLY)
        cz = np.empty(_MAX_POLY)
        lo = np.empty(3)
        hi = np.empty(3)
        l_lo = np.empty(3)
        l_hi = np.empty(3)
        r_lo = np.empty(3)
        r_hi = np.empty(3)
        q_lo = np.empty(3)
        q_hi = np.empty(3)
        for t in range(ci * chunk, min(m, ci * chunk + chunk)):
            o = offset[t]
            w = o
            for v in range(3):
                for a in range(3):
                    tri[v, a] = tris[t, v, a]
            for a in range(3):
                st_lo[0, a] = blo[t, a]
                st_hi[0, a] = bhi[t, a]
            st_n[0] = refs[t]
            sp = 1
            while sp > 0:
                sp -= 1
                for a in range(3):
                    lo[a] = st_lo[sp, a]
                    hi[a] = st_hi[sp, a]
                n = st_n[sp]
                ax = -1
                c = 0.0
                if n > 1:
                    _, ax, c = _importance(lo, hi, s_lo, inv_ext)
                if ax < 0 or sp + 2 > depth:
                    # One reference, or no plane left to cut at: the box as it is.
                    _emit(out_lo, out_hi, out_id, w, lo, hi, t)
                    w += 1
                    continue
                for a in range(3):
                    q_lo[a] = lo[a]
                    q_hi[a] = hi[a]
                q_hi[ax] = c
                has_l = _part_box(tri, q_lo, q_hi, lo, hi, l_lo, l_hi, bx, by, bz, cx, cy, cz)
                q_hi[ax] = hi[ax]
                q_lo[ax] = c
                has_r = _part_box(tri, q_lo, q_hi, lo, hi, r_lo, r_hi, bx, by, bz, cx, cy, cz)
                if has_l and has_r:
                    wl = max(l_hi[0] - l_lo[0], l_hi[1] - l_lo[1], l_hi[2] - l_lo[2])
                    wr = max(r_hi[0] - r_lo[0], r_hi[1] - r_lo[1], r_hi[2] - r_lo[2])
                    nl = int(np.floor(n * wl / (wl + wr) + 0.5)) if wl + wr > 0.0 else n // 2
                    nl = min(max(nl, 1), n - 1)
                    for a in range(3):
                        st_lo[sp, a] = r_lo[a]
                        st_hi[sp, a] = r_hi[a]
                        st_lo[sp + 1, a] = l_lo[a]
                        st_hi[sp + 1, a] = l_hi[a]
                    st_n[sp] = n - nl
                    st_n[sp + 1] = nl
                    sp += 2
                    continue
                # The part lies on one side (it only touches the plane): that side's
                # box, unless it is no smaller (rounding), which ends the cutting here.
                src_lo = l_lo if has_l else r_lo
                src_hi = l_hi if has_l else r_hi
                same = True
                for a in range(3):
                    same = same and src_lo[a] == lo[a] and src_hi[a] == hi[a]
                if not (has_l or has_r) or same:
                    _emit(out_lo, out_hi, out_id, w, lo, hi, t)
                    w += 1
                    continue
                for a in range(3):
                    st_lo[sp, a] = src_lo[a]
                    st_hi[sp, a] = src_hi[a]
                st_n[sp] = n
                sp += 1
            while w < o + refs[t]:
                out_id[w] = -1
                w += 1


def presplit_refs(tris: np.ndarray, budget: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Box references of triangles, the most wasteful boxes cut by spatial splits.

    Parameters
    ----------
    tris : (m, 3, 3) float32
        Triangles (vertex, coordinate).
    budget : float
        Extra references, as a fraction of ``m`` (0: one reference a triangle).

    Returns
    -------
    lo, hi : (r, 3) float32
        Reference boxes, each holding the part of its triangle it stands for.
    ids : (r,) int32
        Triangle of each reference; every triangle has at least one, and the parts
        of a triangle's references cover it.
    """
    tris = np.ascontiguousarray(tris, np.float32)
    m = len(tris)
    blo = np.minimum(np.minimum(tris[:, 0], tris[:, 1]), tris[:, 2])
    bhi = np.maximum(np.maximum(tris[:, 0], tris[:, 1]), tris[:, 2])
    extra = int(budget * m)
    if m == 0 or extra <= 0:
        return blo, bhi, np.arange(m, dtype=np.int32)
    s_lo = blo.min(axis=0).astype(np.float64)
    ext = bhi.max(axis=0).astype(np.float64) - s_lo
    inv_ext = np.where(ext > 0, 1.0 / np.where(ext > 0, ext, 1.0), 0.0)
    blo64 = blo.astype(np.float64)
    bhi64 = bhi.astype(np.float64)
    pri = _priorities(tris, blo64, bhi64, s_lo, inv_ext)
    total = pri.sum()
    refs = np.ones(m, np.int64)
    if total > 0.0:
        # Shares of the budget, rounded down, then one more for the largest remainders
        # (rounding every share down would lose most of the budget to small shares).
        share = np.minimum(pri * (extra / total), MAX_REFS - 1)
        whole = np.floor(share)
        refs += whole.astype(np.int64)
        left = min(extra - int(whole.sum()), int(np.count_nonzero(share - whole > 0)))
        if left > 0:
            top = np.argpartition(-(share - whole), left - 1)[:left]
            refs[top] += 1
    offset = np.concatenate([[0], np.cumsum(refs)[:-1]])
    r = int(refs.sum())
    # float32 out: every box coordinate is a float32 (a vertex's, a float32 step
    # outwards, or a parent's), so the kernel's stores are exact.
    out_lo = np.empty((r, 3), np.float32)
    out_hi = np.empty((r, 3), np.float32)
    out_id = np.empty(r, np.int32)
    _split_all(tris, blo64, bhi64, refs, offset, s_lo, inv_ext, out_lo, out_hi, out_id)
    keep = out_id >= 0
    return out_lo[keep], out_hi[keep], out_id[keep]
