"""Level-by-level RBVH construction kernels (Numba, parallel over the nodes of a level).

The per-node reductions and split choices are plain ``nogil`` kernels over a range of
nodes, spread over threads by :func:`~sparsecast.kernels.parallel.run_chunks`: they
compile in under half the time of ``prange`` loops and run no slower. The partition
kernels stay ``prange`` loops: as plain kernels their per-reference loops ran 2-3x
slower on one thread (dragon, 871 k triangles), for reasons not found.

One level of the build (the paper's Fig. 7) is: per-node reductions over the
primitive references of every frontier node (:func:`node_stats`), the
split-or-rasterize decision (NumPy, in :mod:`.rbvh`), a split plane per node
(:func:`choose_splits`), then compaction of the references into the next
level's array (:func:`partition_counts` sizes it, :func:`partition_write` fills
it), duplicating primitives near the split plane.

References of node ``i`` are ``refs[start[i] : start[i] + count[i]]``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels.parallel import run_chunks

# Columns of the node_stats table.
S_AREA, S_NX, S_NY, S_NZ = 0, 1, 2, 3
S_LO, S_HI = 4, 7  # primitive-box bounds (3 each)
S_CLO, S_CHI = 10, 13  # centroid bounds (3 each)
S_CURVY, S_COMP_LO, S_COMP_HI, S_COMP_2, S_OUT_AREA = 16, 17, 18, 19, 20
N_STATS = 21

# Partition modes.
SPLIT_DUP, SPLIT_PLANE, SPLIT_OBJECT, SPLIT_HALF = 0, 1, 2, 3


@njit(cache=True)
def _find(parent, a):
    while parent[a] != a:
        parent[a] = parent[parent[a]]  # path halving
        a = parent[a]
    return a


@njit(cache=True)
def face_components(faces, n_vertices):
    """Connected-component label of every face (union-find over shared vertices)."""
    parent = np.arange(n_vertices).astype(np.int32)
    for f in range(faces.shape[0]):
        r0 = _find(parent, faces[f, 0])
        for c in range(1, 3):
            r = _find(parent, faces[f, c])
            if r != r0:
                parent[r] = r0
    out = np.empty(faces.shape[0], np.int32)
    for f in range(faces.shape[0]):
        out[f] = _find(parent, faces[f, 0])
    return out


@njit(cache=True)
def triangle_prims(tris, faces, face_normals, vertex_normals, cos_curved):
    """Per triangle: box, box centre, and the share of its corners at curved vertices.

    A vertex is curved when some adjacent face normal makes a cosine below
    ``cos_curved`` with its (smooth) normal.
    """
    m = tris.shape[0]
    pmin = np.empty((m, 3))
    pmax = np.empty((m, 3))
    vmin = np.ones(vertex_normals.shape[0])
    for f in range(m):
        for a in range(3):
            pmin[f, a] = min(tris[f, 0, a], tris[f, 1, a], tris[f, 2, a])
            pmax[f, a] = max(tris[f, 0, a], tris[f, 1, a], tris[f, 2, a])
        for c in range(3):
            v = faces[f, c]
            cs = (vertex_normals[v, 0] * face_normals[f, 0] + vertex_normals[v, 1] * face_normals[f, 1]
                  + vertex_normals[v, 2] * face_normals[f, 2])
            vmin[v] = min(vmin[v], cs)
    curvy = np.empty(m)
    for f in range(m):
        n = 0
        for c in range(3):
            n += vmin[faces[f, c]] < cos_curved
        curvy[f] = n / 3.0
    return pmin, pmax, 0.5 * (pmin + pmax), curvy


def node_stats(refs, start, count, pmin, pmax, pcent, pnorm, parea, pcurvy, pcomp, cos_phi):
    """Per-node reductions: area, area-weighted normal sum, bounds, centroid bounds,
    curvy-corner sum, the component range, and the area whose normals leave the
    cone of half-angle ``acos(cos_phi)`` around the mean normal: ``(n_nodes, N_STATS)``."""
    out = np.empty((start.shape[0], N_STATS))
    run_chunks(_node_stats, start.shape[0], None, refs, start, count, pmin, pmax, pcent, pnorm, parea, pcurvy,
               pcomp, cos_phi, out)
    return out


@njit(cache=True, nogil=True)
def _node_stats(first, last, refs, start, count, pmin, pmax, pcent, pnorm, parea, pcurvy, pcomp, cos_phi, out):
    for i in range(first, last):
        s, e = start[i], start[i] + count[i]
        a = nx = ny = nz = curvy = 0.0
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        clo = np.full(3, np.inf)
        chi = np.full(3, -np.inf)
        c_lo, c_hi = 2147483647, -1
        for r in range(s, e):
            p = refs[r]
            w = parea[p]
            a += w
            nx += w * pnorm[p, 0]
            ny += w * pnorm[p, 1]
            nz += w * pnorm[p, 2]
            curvy += pcurvy[p]
            for k in range(3):
                lo[k] = min(lo[k], pmin[p, k])
                hi[k] = max(hi[k], pmax[p, k])
                clo[k] = min(clo[k], pcent[p, k])
                chi[k] = max(chi[k], pcent[p, k])
            c_lo = min(c_lo, pcomp[p])
            c_hi = max(c_hi, pcomp[p])
        ln = math.sqrt(nx * nx + ny * ny + nz * nz)
        out_area = a
        two = 1.0  # 1 when every primitive belongs to component c_lo or c_hi
        if ln > 0.0:
            out_area = 0.0
            for r in range(s, e):
                p = refs[r]
                c = (pnorm[p, 0] * nx + pnorm[p, 1] * ny + pnorm[p, 2] * nz) / ln
                if c < cos_phi:
                    out_area += parea[p]
        for r in range(s, e):
            c = pcomp[refs[r]]
            if c != c_lo and c != c_hi:
                two = 0.0
                break
        out[i, S_AREA], out[i, S_NX], out[i, S_NY], out[i, S_NZ] = a, nx, ny, nz
        for k in range(3):
            out[i, S_LO + k] = lo[k]
            out[i, S_HI + k] = hi[k]
            out[i, S_CLO + k] = clo[k]
            out[i, S_CHI + k] = chi[k]
        out[i, S_CURVY] = curvy
        out[i, S_COMP_LO] = c_lo
        out[i, S_COMP_HI] = c_hi
        out[i, S_COMP_2] = two if c_hi != c_lo else 0.0
        out[i, S_OUT_AREA] = out_area


@njit(cache=True, inline="always")
def _surface(lx, ly, lz, hx, hy, hz):
    ex, ey, ez = max(hx - lx, 0.0), max(hy - ly, 0.0), max(hz - lz, 0.0)
    return ex * ey + ey * ez + ez * ex


def choose_splits(refs, start, count, stats, pmin, pmax, pcent, parea, use_sah, n_bins):
    """Split axis and position per node.

    ``use_sah``: the RBVH SAH ``C = p(b|a) A(b) + p(c|a) A(c)`` with
    ``p = S(child box) / S(parent box)`` and ``A`` the surface area of the
    primitives, over ``n_bins`` centroid bins on each axis; else the spatial
    median of the centroid bounds on the longest axis.
    """
    axis_out = np.zeros(start.shape[0], np.int32)
    pos_out = np.zeros(start.shape[0])
    run_chunks(_choose_splits, start.shape[0], None, refs, start, count, stats, pmin, pmax, pcent, parea,
               use_sah, n_bins, axis_out, pos_out)
    return axis_out, pos_out


@njit(cache=True, nogil=True)
def _choose_splits(first, last, refs, start, count, stats, pmin, pmax, pcent, parea, use_sah, n_bins,
                   axis_out, pos_out):
    for i in range(first, last):
        s, e = start[i], start[i] + count[i]
        best_axis = 0
        best_ext = -1.0
        for k in range(3):
            ext = stats[i, S_CHI + k] - stats[i, S_CLO + k]
            if ext > best_ext:
                best_axis, best_ext = k, ext
        best_pos = stats[i, S_CLO + best_axis] + 0.5 * best_ext
        if use_sah and best_ext > 0.0:
            parent = _surface(stats[i, S_LO], stats[i, S_LO + 1], stats[i, S_LO + 2],
                              stats[i, S_HI], stats[i, S_HI + 1], stats[i, S_HI + 2])
            area = np.zeros(n_bins)
            blo = np.empty((n_bins, 3))
            bhi = np.empty((n_bins, 3))
            r_cost = np.empty(n_bins)
            best_cost = np.inf
            for k in range(3):
                c0 = stats[i, S_CLO + k]
                ext = stats[i, S_CHI + k] - c0
                if ext <= 0.0:
                    continue
                area[:] = 0.0
                blo[:] = np.inf
                bhi[:] = -np.inf
                scale = n_bins / ext
                for r in range(s, e):
                    p = refs[r]
                    b = min(int((pcent[p, k] - c0) * scale), n_bins - 1)
                    area[b] += parea[p]
                    for a in range(3):
                        blo[b, a] = min(blo[b, a], pmin[p, a])
                        bhi[b, a] = max(bhi[b, a], pmax[p, a])
                lo0 = lo1 = lo2 = np.inf
                hi0 = hi1 = hi2 = -np.inf
                acc = 0.0
                for b in range(n_bins - 1, 0, -1):
                    lo0, lo1, lo2 = min(lo0, blo[b, 0]), min(lo1, blo[b, 1]), min(lo2, blo[b, 2])
                    hi0, hi1, hi2 = max(hi0, bhi[b, 0]), max(hi1, bhi[b, 1]), max(hi2, bhi[b, 2])
                    acc += area[b]
                    r_cost[b] = _surface(lo0, lo1, lo2, hi0, hi1, hi2) * acc if acc > 0 else -1.0
                lo0 = lo1 = lo2 = np.inf
                hi0 = hi1 = hi2 = -np.inf
                acc = 0.0
                for b in range(1, n_bins):
                    lo0, lo1, lo2 = min(lo0, blo[b - 1, 0]), min(lo1, blo[b - 1, 1]), min(lo2, blo[b - 1, 2])
                    hi0, hi1, hi2 = max(hi0, bhi[b - 1, 0]), max(hi1, bhi[b - 1, 1]), max(hi2, bhi[b - 1, 2])
                    acc += area[b - 1]
                    if acc <= 0.0 or r_cost[b] < 0.0:
                        continue
                    cost = (_surface(lo0, lo1, lo2, hi0, hi1, hi2) * acc + r_cost[b]) / max(parent, 1e-300)
                    if cost < best_cost:
                        best_cost, best_axis, best_pos = cost, k, c0 + b * ext / n_bins
        axis_out[i] = best_axis
        pos_out[i] = best_pos


@njit(cache=True, inline="always")
def _sides(j, n, p, mode, axis, pos, band, comp_hi, pmin, pmax, pcent, pcomp):
    """``(left, right)`` membership of reference ``j`` (of ``n``) holding primitive ``p``."""
    if mode == SPLIT_HALF:
        return j < n // 2, j >= n // 2
    if mode == SPLIT_OBJECT:
        return pcomp[p] != comp_hi, pcomp[p] == comp_hi
    left = pcent[p, axis] < pos
    if mode == SPLIT_DUP and pmax[p, axis] >= pos - band and pmin[p, axis] <= pos + band:
        return True, True
    return left, not left


@njit(cache=True, parallel=True)
def partition_counts(refs, start, count, mode_in, axis, pos, band, comp_hi, pmin, pmax, pcent, pcomp):
    """Children sizes per node, and the partition mode that keeps both non-empty.

    Duplication (``SPLIT_DUP``) falls back to a plain plane split when one child
    would receive every primitive, and a plane split falls back to
    halving the reference list when one side would be empty.
    """
    n_nodes = start.shape[0]
    nl = np.zeros(n_nodes, np.int64)
    nr = np.zeros(n_nodes, np.int64)
    mode = mode_in.copy()
    for i in prange(n_nodes):
        s, n = start[i], count[i]
        for attempt in range(3):
            a = b = 0
            for j in range(n):
                l, r = _sides(j, n, refs[s + j], mode[i], axis[i], pos[i], band[i], comp_hi[i],
                              pmin, pmax, pcent, pcomp)
                a += l
                b += r
            # A child holding every reference would repeat its parent forever.
            if (mode[i] == SPLIT_DUP and (a == n or b == n)) or a == 0 or b == 0:
                mode[i] = SPLIT_PLANE if mode[i] == SPLIT_DUP else SPLIT_HALF
                continue
            break
        nl[i], nr[i] = a, b
    return nl, nr, mode


@njit(cache=True, parallel=True)
def partition_write(refs, start, count, mode, axis, pos, band, comp_hi, pmin, pmax, pcent, pcomp,
                    out, left_start, right_start):
    """Write every split node's references into its children's ranges of ``out``."""
    for i in prange(start.shape[0]):
        s, n = start[i], count[i]
        a, b = left_start[i], right_start[i]
        for j in range(n):
            p = refs[s + j]
            l, r = _sides(j, n, p, mode[i], axis[i], pos[i], band[i], comp_hi[i], pmin, pmax, pcent, pcomp)
            if l:
                out[a] = p
                a += 1
            if r:
                out[b] = p
                b += 1


@njit(cache=True)
def refit(node_bounds, node_child, node_count):
    """Inner-node bounds from their children (children always follow their parent)."""
    for k in range(node_bounds.shape[0] - 1, -1, -1):
        if node_count[k] == 0:
            c = node_child[k]
            for a in range(3):
                node_bounds[k, 0, a] = min(node_bounds[c, 0, a], node_bounds[c + 1, 0, a])
                node_bounds[k, 1, a] = max(node_bounds[c, 1, a], node_bounds[c + 1, 1, a])
