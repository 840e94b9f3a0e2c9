"""Atlas rasterization kernels (Numba, parallel over tiles; each tile owns its texels:
plain ``nogil`` kernels over a range of tiles, spread over threads by
:func:`~sparsecast.kernels.parallel.run_chunks`).

Conventions as in :mod:`._rbvh_kernels`: texel ``(i, j)`` of tile ``k`` sits at
texel coordinates ``(s, t) = (i, j)`` and is stored in the pool at
``depth[o + j * r + i]`` (``tile_texels[k] = (o, r)``: offset and edge); depth is
the height along ``W`` and the surface kept is the one nearest to a viewer on the
``+W`` side (the largest height).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kernels.parallel import run_chunks
from ._rbvh_kernels import EMPTY, EMPTY_TEST

#: barycentric slack so texels exactly on a shared edge are covered by both triangles
EDGE_EPS = 1e-6


@njit(cache=True, inline="always")
def _to_tile(P, x, y, z):
    rx, ry, rz = x - P[0], y - P[1], z - P[2]
    return (rx * P[3] + ry * P[4] + rz * P[5], rx * P[6] + ry * P[7] + rz * P[8],
            rx * P[9] + ry * P[10] + rz * P[11])


def rasterize_triangles(tile_proj, tile_texels, tile_start, tile_count, refs, tris, faces, vnormals,
                        depth, normal):
    """Depth (max height) and interpolated vertex normal of each tile's triangles.

    Rasterization is conservative: a texel is also written when its centre lies
    outside a triangle but the triangle overlaps the 2 x 2 texel square around it
    (the union of the four bilinear cells that share the texel), with the
    triangle's plane extrapolated to the texel centre. Then every point of every
    triangle falls in a cell whose four corners are valid, so a tile covers its
    triangles completely and tiles that share an edge overlap across it: no
    cracks, and the extrapolated rim (under one texel) is the tile's safety
    border. Texels with their centre inside some triangle always win over
    extrapolated ones; among extrapolations the least-outside triangle wins.
    """
    run_chunks(_rasterize_triangles, tile_proj.shape[0], None, tile_proj, tile_texels, tile_start, tile_count,
               refs, tris, faces, vnormals, depth, normal)


@njit(cache=True, nogil=True)
def _rasterize_triangles(first, last, tile_proj, tile_texels, tile_start, tile_count, refs, tris, faces,
                         vnormals, depth, normal):
    for k in range(first, last):
        P = tile_proj[k]
        o, r = tile_texels[k, 0], tile_texels[k, 1]
        # > 0 inside some triangle; <= 0: how far outside the writer's triangle was
        score = np.full((r, r), -np.inf)
        for q in range(tile_start[k], tile_start[k] + tile_count[k]):
            f = refs[q]
            s0, t0, h0 = _to_tile(P, tris[f, 0, 0], tris[f, 0, 1], tris[f, 0, 2])
            s1, t1, h1 = _to_tile(P, tris[f, 1, 0], tris[f, 1, 1], tris[f, 1, 2])
            s2, t2, h2 = _to_tile(P, tris[f, 2, 0], tris[f, 2, 1], tris[f, 2, 2])
            area2 = (s1 - s0) * (t2 - t0) - (s2 - s0) * (t1 - t0)
            if abs(area2) < 1e-12:
                continue  # edge-on in this projection: covers no area
            inv = 1.0 / area2
            # Barycentric gradients; b0 = 1 - b1 - b2.
            g1s, g1t = (t2 - t0) * inv, -(s2 - s0) * inv
            g2s, g2t = -(t1 - t0) * inv, (s1 - s0) * inv
            r0 = abs(g1s + g2s) + abs(g1t + g2t)  # reach of each b over +-1 texel
            r1 = abs(g1s) + abs(g1t)
            r2 = abs(g2s) + abs(g2t)
            i_lo = max(0, int(math.floor(min(s0, s1, s2))))
            i_hi = min(r - 1, int(math.ceil(max(s0, s1, s2))))
            j_lo = max(0, int(math.floor(min(t0, t1, t2))))
            j_hi = min(r - 1, int(math.ceil(max(t0, t1, t2))))
            v0, v1, v2 = faces[f, 0], faces[f, 1], faces[f, 2]
            for j in range(j_lo, j_hi + 1):
                for i in range(i_lo, i_hi + 1):
                    b1 = ((i - s0) * (t2 - t0) - (s2 - s0) * (j - t0)) * inv
                    b2 = ((s1 - s0) * (j - t0) - (i - s0) * (t1 - t0)) * inv
                    b0 = 1.0 - b1 - b2
                    m = min(b0, b1, b2)
                    h = b0 * h0 + b1 * h1 + b2 * h2
                    if m >= -EDGE_EPS:
                        if score[j, i] > 0.0 and h <= depth[o + j * r + i]:
                            continue
                        score[j, i] = 1.0
                    else:
                        # Separating-axis test of the triangle against the open
                        # square of half-width 1 around the texel.
                        if b0 + r0 <= 0.0 or b1 + r1 <= 0.0 or b2 + r2 <= 0.0 or score[j, i] >= m:
                            continue
                        score[j, i] = m
                        # Normal from the nearest point's barycentrics.
                        b0, b1, b2 = max(b0, 0.0), max(b1, 0.0), max(b2, 0.0)
                        sb = b0 + b1 + b2
                        b0, b1, b2 = b0 / sb, b1 / sb, b2 / sb
                    depth[o + j * r + i] = h
                    for c in range(3):
                        normal[o + j * r + i, c] = (b0 * vnormals[v0, c] + b1 * vnormals[v1, c]
                                                     + b2 * vnormals[v2, c])


def splat_points(tile_proj, tile_texels, tile_steps, tile_start, tile_count, refs, points, pnormals, radii,
                 depth, normal):
    """Oriented discs: every texel whose column meets a disc gets the disc's height there.

    ``tile_steps[k]`` is the world size of a texel along ``U`` and ``V``.
    """
    run_chunks(_splat_points, tile_proj.shape[0], None, tile_proj, tile_texels, tile_steps, tile_start, tile_count,
               refs, points, pnormals, radii, depth, normal)


@njit(cache=True, nogil=True)
def _splat_points(first, last, tile_proj, tile_texels, tile_steps, tile_start, tile_count, refs, points, pnormals,
                  radii, depth, normal):
    for k in range(first, last):
        P = tile_proj[k]
        o, r = tile_texels[k, 0], tile_texels[k, 1]
        du, dv = tile_steps[k, 0], tile_steps[k, 1]
        for q in range(tile_start[k], tile_start[k] + tile_count[k]):
            p = refs[q]
            sc, tc, hc = _to_tile(P, points[p, 0], points[p, 1], points[p, 2])
            # Disc normal in the tile frame (U, V scaled back to unit axes).
            nu = (pnormals[p, 0] * P[3] + pnormals[p, 1] * P[4] + pnormals[p, 2] * P[5]) * du
            nv = (pnormals[p, 0] * P[6] + pnormals[p, 1] * P[7] + pnormals[p, 2] * P[8]) * dv
            nw = pnormals[p, 0] * P[9] + pnormals[p, 1] * P[10] + pnormals[p, 2] * P[11]
            if abs(nw) < 1e-6:
                continue
            rad = radii[p]
            i_lo = max(0, int(math.ceil(sc - rad / du)))
            i_hi = min(r - 1, int(math.floor(sc + rad / du)))
            j_lo = max(0, int(math.ceil(tc - rad / dv)))
            j_hi = min(r - 1, int(math.floor(tc + rad / dv)))
            for j in range(j_lo, j_hi + 1):
                for i in range(i_lo, i_hi + 1):
                    eu = (i - sc) * du
                    ev = (j - tc) * dv
                    eh = -(nu * eu + nv * ev) / nw  # stay in the disc's plane
                    if eu * eu + ev * ev + eh * eh > rad * rad:
                        continue
                    h = hc + eh
                    if h > depth[o + j * r + i]:
                        depth[o + j * r + i] = h
                        normal[o + j * r + i, 0] = pnormals[p, 0]
                        normal[o + j * r + i, 1] = pnormals[p, 1]
                        normal[o + j * r + i, 2] = pnormals[p, 2]


def dilate(tile_texels, tile_steps, depth, normal, passes, max_slope):
    """Grow every tile's surface by ``passes`` texels into empty texels.

    A new depth extrapolates the neighbour's with its gradient (``2 h1 - h2``
    along each direction that has two valid texels and a slope of at most
    ``max_slope``, else ``h1``: a cliff, such as a crease seen edge-on, would
    shoot the border far out), averaged over directions; the normal is the
    neighbours' mean. The border keeps adjacent tiles overlapping, so rays
    through a seam find a surface (no cracks).
    """
    run_chunks(_dilate, tile_texels.shape[0], None, tile_texels, tile_steps, depth, normal, passes, max_slope)


@njit(cache=True, nogil=True)
def _dilate(first, last, tile_texels, tile_steps, depth, normal, passes, max_slope):
    for k in range(first, last):
        o, r = tile_texels[k, 0], tile_texels[k, 1]
        step = min(tile_steps[k, 0], tile_steps[k, 1])
        for _ in range(passes):
            d_old = depth[o:o + r * r].copy().reshape((r, r))
            for j in range(r):
                for i in range(r):
                    if d_old[j, i] > EMPTY_TEST:
                        continue
                    acc = 0.0
                    cnt = 0
                    nx = ny = nz = 0.0
                    # Eight neighbours: with four, the diagonal texel at a convex
                    # corner of the covered region stays empty and its cells leave
                    # a pinhole where three tiles meet.
                    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1)):
                        i1, j1 = i + di, j + dj
                        if i1 < 0 or i1 >= r or j1 < 0 or j1 >= r or d_old[j1, i1] < EMPTY_TEST:
                            continue
                        h1 = d_old[j1, i1]
                        i2, j2 = i1 + di, j1 + dj
                        if (0 <= i2 < r and 0 <= j2 < r and d_old[j2, i2] > EMPTY_TEST
                                and abs(h1 - d_old[j2, i2]) <= max_slope * step):
                            acc += 2.0 * h1 - d_old[j2, i2]
                        else:
                            acc += h1
                        cnt += 1
                        nx += normal[o + j1 * r + i1, 0]
                        ny += normal[o + j1 * r + i1, 1]
                        nz += normal[o + j1 * r + i1, 2]
                    if cnt > 0:
                        depth[o + j * r + i] = acc / cnt
                        normal[o + j * r + i, 0] = nx / cnt
                        normal[o + j * r + i, 1] = ny / cnt
                        normal[o + j * r + i, 2] = nz / cnt


def tile_height_range(tile_texels, depth, pad):
    """``(min, max)`` valid height per tile, widened by ``pad`` (tiles may be empty: (0, -1))."""
    out = np.empty((tile_texels.shape[0], 2), np.float32)
    run_chunks(_tile_height_range, tile_texels.shape[0], None, tile_texels, depth, pad, out)
    return out


@njit(cache=True, nogil=True)
def _tile_height_range(first, last, tile_texels, depth, pad, out):
    for k in range(first, last):
        o, r = tile_texels[k, 0], tile_texels[k, 1]
        lo, hi = np.inf, -np.inf
        for j in range(r):
            for i in range(r):
                h = depth[o + j * r + i]
                if h > EMPTY_TEST:
                    lo = min(lo, h)
                    hi = max(hi, h)
        if lo > hi:
            out[k, 0], out[k, 1] = 0.0, -1.0
        else:
            out[k, 0], out[k, 1] = lo - pad[k], hi + pad[k]


def triangle_tile_extents(frames, tile_start, tile_count, refs, tris):
    """Per tile: bounds of its triangles in the tile frame ``(u, v, w)`` and in world space.

    Returns ``(lo, hi, world_lo, world_hi)``, each ``(T, 3)``.
    """
    n = frames.shape[0]
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    wlo = np.full((n, 3), np.inf)
    whi = np.full((n, 3), -np.inf)
    run_chunks(_triangle_tile_extents, n, None, frames, tile_start, tile_count, refs, tris, lo, hi, wlo, whi)
    return lo, hi, wlo, whi


@njit(cache=True, nogil=True)
def _triangle_tile_extents(first, last, frames, tile_start, tile_count, refs, tris, lo, hi, wlo, whi):
    for k in range(first, last):
        for q in range(tile_start[k], tile_start[k] + tile_count[k]):
            f = refs[q]
            for c in range(3):
                x, y, z = tris[f, c, 0], tris[f, c, 1], tris[f, c, 2]
                for a in range(3):
                    p = frames[k, a, 0] * x + frames[k, a, 1] * y + frames[k, a, 2] * z
                    lo[k, a] = min(lo[k, a], p)
                    hi[k, a] = max(hi[k, a], p)
                wlo[k, 0], whi[k, 0] = min(wlo[k, 0], x), max(whi[k, 0], x)
                wlo[k, 1], whi[k, 1] = min(wlo[k, 1], y), max(whi[k, 1], y)
                wlo[k, 2], whi[k, 2] = min(wlo[k, 2], z), max(whi[k, 2], z)


__all__ = ["rasterize_triangles", "splat_points", "dilate", "tile_height_range", "triangle_tile_extents", "EMPTY"]
