"""Cell occupancy of the k-d trees: cell classification and partial summed-volume
tables (SVTs) with their tight-box and count queries (Numba kernels; the split is in
:mod:`.split`).

Cells
-----
Cell ``(cz, cy, cx)`` is the unit cube between voxels ``c`` and ``c + 1`` on each
axis (index space), clipped to the domain; an axis of ``n`` voxels has
``max(n - 1, 1)`` cells. A cell is *occupied* when the TF opacity is non-zero for
some value in ``[min, max]`` of its own eight corners, the voxels ``c .. c + 1`` on
each axis (``apron=0``; the k-d trees, which grow their boxes instead, see
:mod:`.build`), or of the voxels ``c - 1 .. c + 2`` (``apron=1``: the one-voxel apron of
docs/architecture.md, "Emptiness", which the hybrids' grids keep: every cell whose own
corner range is non-empty is then occupied together with its 26 neighbours, so a
lattice sample that rounding puts an ulp outside its cell is still inside the
occupied set).

Partial SVTs
------------
Cells are grouped in bricks of ``SVT_BRICK = 32`` cells per edge. For every brick
with at least one occupied cell, ``svt[slot]`` (shape ``(33, 33, 33)``, uint16)
holds the inclusive 3-D prefix counts of its occupied cells with a zero pad
(``svt[s, z + 1, y + 1, x + 1]`` = occupied cells of the brick in local
``[0..z] x [0..y] x [0..x]``), so the occupied count of any sub-box of a brick
takes 8 look-ups. ``bslot[bz, by, bx]`` is the slot (-1: empty brick),
``bcount`` the brick's count and ``bbox[bz, by, bx]`` its tight box
``(x0, y0, z0, x1, y1, z1)`` (global cells, half-open). The tight box of the
occupied cells of any box is the union of per-brick answers: a brick whose tight
box lies inside the query contributes it as is, a fully occupied brick
contributes the intersection, any other overlapping brick shrinks the
intersection face by face with binary searches on its SVT.

Boxes are ``(x0, y0, z0, x1, y1, z1)`` in cells, half-open, axis 0 = x.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ...kernels.classify import entry_span, range_is_empty
from ...kernels.layout import row_offset, voxel_parts
from ...kernels.parallel import run_chunks

SVT_BRICK = 32
#: cells per brick edge of the coarse classification pre-pass (Volume.brick_stats)
CLASSIFY_BRICK = 8


# --------------------------------------------------------------------------- classify
def classify_cells(data, bricks, bvmin, bvmax, prefix, v_lo, scale, ncz, ncy, ncx, apron, occ) -> None:
    """Write the occupancy of every cell (see the module docstring) into ``occ``.

    ``bricks`` lists the flat numbers of the 8^3 bricks (``CLASSIFY_BRICK``) that
    the volume's brick ranges with apron (``Volume.brick_stats(8)``) classify
    non-empty: brick ``b`` covers cells ``8b .. 8b+7`` whose apron windows
    ``c-1 .. c+2`` all lie in the brick's apron window ``8b-1 .. 8b+9``, so an
    empty brick has only empty cells and its voxels are never read. ``occ`` must
    be zero on entry; ``apron`` (0 or 1) widens each cell's window by that many
    voxels on every side; ``occ[i]`` (8, 8, 8) receives the cells of brick
    ``bricks[i]`` (cells outside the volume stay 0). ``bvmin/bvmax[i]`` is that
    brick's apron range: when every TF entry it spans is opaque, every cell (whose
    range lies inside) is occupied and no voxel is read. Otherwise each cell's range is reduced axis by axis (x, y, z) over its
    4-voxel windows. ``data`` is a dense ``(nz, ny, nx)`` array or a bricked volume's
    :class:`~sparsecast.kernels.bricked.BrickedVoxels` with those bricks resident
    (storage bricks a multiple of 8 cells, so each 8^3 brick's window lies in one slot).
    """
    run_chunks(_classify_bricks, bricks.shape[0], 16, data, bricks, bvmin, bvmax, prefix, v_lo, scale,
               ncz, ncy, ncx, apron, occ)


@njit(cache=True, nogil=True)
def _classify_bricks(first, last, data, bricks, bvmin, bvmax, prefix, v_lo, scale, ncz, ncy, ncx, apron, occ):
    """:func:`classify_cells` for ``bricks[first:last]``."""
    flat, pages, nx, ny, nz, snbx, snby, shift = voxel_parts(data)
    B = CLASSIFY_BRICK
    nby = -(-ncy // B)
    nbx = -(-ncx // B)
    mx_lo = np.empty((B + 3, B + 3, B), np.float64)
    mx_hi = np.empty((B + 3, B + 3, B), np.float64)
    my_lo = np.empty((B + 3, B, B), np.float64)
    my_hi = np.empty((B + 3, B, B), np.float64)
    for bi in range(first, last):
        fb = bricks[bi]
        bz = fb // (nby * nbx)
        rem = fb - bz * nby * nbx
        by = rem // nbx
        bx = rem - by * nbx
        cz0 = bz * B
        cy0 = by * B
        cx0 = bx * B
        cz1 = min(cz0 + B, ncz)
        cy1 = min(cy0 + B, ncy)
        cx1 = min(cx0 + B, ncx)
        first, last = entry_span(v_lo, scale, prefix.shape[0] - 1, bvmin[bi], bvmax[bi])
        if prefix[last + 1] - prefix[first] == last - first + 1:
            for z in range(cz1 - cz0):
                for y in range(cy1 - cy0):
                    for x in range(cx1 - cx0):
                        occ[bi, z, y, x] = 1
            continue
        wz0 = max(cz0 - apron, 0)
        wy0 = max(cy0 - apron, 0)
        wz1 = min(cz1 + apron, nz - 1)
        wy1 = min(cy1 + apron, ny - 1)
        lz = wz1 - wz0 + 1
        ly = wy1 - wy0 + 1
        for zz in range(lz):
            for yy in range(ly):
                # The row of voxels, from the dense array or the brick's slot
                # (the window lies in the slot of the storage brick of cell (cz0, cy0, cx0)).
                base = row_offset(pages, shift, snbx, snby, nx, ny, cz0, cy0, cx0, wz0 + zz, wy0 + yy)
                for cx in range(cx0, cx1):
                    i0 = max(cx - apron, 0)
                    i1 = min(cx + 1 + apron, nx - 1)
                    lo = np.float64(flat[base + i0])
                    hi = lo
                    for i in range(i0 + 1, i1 + 1):
                        v = np.float64(flat[base + i])
                        if v < lo:
                            lo = v
                        if v > hi:
                            hi = v
                    mx_lo[zz, yy, cx - cx0] = lo
                    mx_hi[zz, yy, cx - cx0] = hi
        # The y and z passes below are the same window reduction along two axes, written
        # out: one helper for both (a plane index, the z pass over (y, x) flattened) took
        # 8-15 % longer to classify (tooth, mni152, bonsai; 3 alternating pairs of processes).
        for zz in range(lz):
            for cy in range(cy0, cy1):
                j0 = max(cy - apron, 0) - wy0
                j1 = min(cy + 1 + apron, ny - 1) - wy0
                for xx in range(cx1 - cx0):
                    lo = mx_lo[zz, j0, xx]
                    hi = mx_hi[zz, j0, xx]
                    for j in range(j0 + 1, j1 + 1):
                        if mx_lo[zz, j, xx] < lo:
                            lo = mx_lo[zz, j, xx]
                        if mx_hi[zz, j, xx] > hi:
                            hi = mx_hi[zz, j, xx]
                    my_lo[zz, cy - cy0, xx] = lo
                    my_hi[zz, cy - cy0, xx] = hi
        for cz in range(cz0, cz1):
            k0 = max(cz - apron, 0) - wz0
            k1 = min(cz + 1 + apron, nz - 1) - wz0
            for yy in range(cy1 - cy0):
                for xx in range(cx1 - cx0):
                    lo = my_lo[k0, yy, xx]
                    hi = my_hi[k0, yy, xx]
                    for k in range(k0 + 1, k1 + 1):
                        if my_lo[k, yy, xx] < lo:
                            lo = my_lo[k, yy, xx]
                        if my_hi[k, yy, xx] > hi:
                            hi = my_hi[k, yy, xx]
                    if not range_is_empty(prefix, v_lo, scale, lo, hi):
                        occ[bi, cz - cz0, yy, xx] = 1


# --------------------------------------------------------------------------- SVTs
@njit(cache=True, inline="always")
def _occ_at(bmap, occ, z, y, x):
    """Occupancy of cell ``(z, y, x)`` stored per 8^3 brick (``bmap``: row or -1)."""
    b = bmap[z >> 3, y >> 3, x >> 3]
    if b < 0:
        return 0
    return occ[b, z & 7, y & 7, x & 7]


def brick_counts(bmap, occ, ncz, ncy, ncx, bcount, bbox) -> None:
    """Per 32^3 brick: occupied count and tight box (empty bricks: count 0).

    Cells live in per-8^3-brick arrays (``occ[bmap[z>>3, y>>3, x>>3]]``); 8^3
    bricks without a row are empty and not visited.
    """
    run_chunks(_brick_counts, bcount.size, 8, bmap, occ, ncz, ncy, ncx, bcount, bbox)


@njit(cache=True, nogil=True)
def _brick_counts(first, last, bmap, occ, ncz, ncy, ncx, bcount, bbox):
    """:func:`brick_counts` for the 32^3 bricks ``first .. last - 1`` (flat, C order)."""
    nbz, nby, nbx = bcount.shape
    S = SVT_BRICK
    F = S // CLASSIFY_BRICK
    B = CLASSIFY_BRICK
    for flat in range(first, last):
        bz = flat // (nby * nbx)
        rem = flat - bz * nby * nbx
        by = rem // nbx
        bx = rem - by * nbx
        n = 0
        lx = 1 << 30
        ly = 1 << 30
        lz = 1 << 30
        hx = -1
        hy = -1
        hz = -1
        for sz in range(bz * F, min(bz * F + F, bmap.shape[0])):
            for sy in range(by * F, min(by * F + F, bmap.shape[1])):
                for sx in range(bx * F, min(bx * F + F, bmap.shape[2])):
                    b = bmap[sz, sy, sx]
                    if b < 0:
                        continue
                    for z in range(B):
                        for y in range(B):
                            for x in range(B):
                                if occ[b, z, y, x]:
                                    n += 1
                                    gz = sz * B + z
                                    gy = sy * B + y
                                    gx = sx * B + x
                                    lx = min(lx, gx)
                                    ly = min(ly, gy)
                                    lz = min(lz, gz)
                                    hx = max(hx, gx + 1)
                                    hy = max(hy, gy + 1)
                                    hz = max(hz, gz + 1)
        bcount[bz, by, bx] = n
        if n == 0:
            lx = ly = lz = hx = hy = hz = 0
        bbox[bz, by, bx, 0] = lx
        bbox[bz, by, bx, 1] = ly
        bbox[bz, by, bx, 2] = lz
        bbox[bz, by, bx, 3] = hx
        bbox[bz, by, bx, 4] = hy
        bbox[bz, by, bx, 5] = hz


def build_svts(bmap, occ, bslot, svt) -> None:
    """Fill the partial SVT of every non-empty 32^3 brick (parallel over bricks)."""
    run_chunks(_build_svts, bslot.size, 8, bmap, occ, bslot, svt)


@njit(cache=True, nogil=True)
def _build_svts(first, last, bmap, occ, bslot, svt):
    """:func:`build_svts` for the 32^3 bricks ``first .. last - 1`` (flat, C order)."""
    nbz, nby, nbx = bslot.shape
    S = SVT_BRICK
    for flat in range(first, last):
        bz = flat // (nby * nbx)
        rem = flat - bz * nby * nbx
        by = rem // nbx
        bx = rem - by * nbx
        s = bslot[bz, by, bx]
        if s < 0:
            continue
        z0 = bz * S
        y0 = by * S
        x0 = bx * S
        t = svt[s]
        t[0, :, :] = 0
        t[:, 0, :] = 0
        t[:, :, 0] = 0
        mz = bmap.shape[0] * 8
        my = bmap.shape[1] * 8
        mx = bmap.shape[2] * 8
        for z in range(S):
            for y in range(S):
                row = 0
                for x in range(S):
                    gz = z0 + z
                    gy = y0 + y
                    gx = x0 + x
                    if gz < mz and gy < my and gx < mx:
                        row += _occ_at(bmap, occ, gz, gy, gx)
                    t[z + 1, y + 1, x + 1] = row + t[z + 1, y, x + 1]
            for y in range(S):
                for x in range(S):
                    t[z + 1, y + 1, x + 1] += t[z, y + 1, x + 1]


@njit(cache=True, inline="always")
def _svt_count(t, x0, y0, z0, x1, y1, z1):
    """Occupied cells of local half-open box ``[x0, x1) x [y0, y1) x [z0, z1)``."""
    return (
        np.int64(t[z1, y1, x1]) - np.int64(t[z0, y1, x1]) - np.int64(t[z1, y0, x1])
        - np.int64(t[z1, y1, x0]) + np.int64(t[z0, y0, x1]) + np.int64(t[z0, y1, x0])
        + np.int64(t[z1, y0, x0]) - np.int64(t[z0, y0, x0])
    )


@njit(cache=True)
def _shrink(t, b):
    """Shrink local box ``b`` (6 ints, modified in place; count > 0) to its tight box."""
    for ax in range(3):
        keep_hi = b[ax + 3]
        # low face: smallest c with count([b[ax], c + 1)) > 0
        lo = b[ax]
        hi = keep_hi - 1
        while lo < hi:
            mid = (lo + hi) // 2
            b[ax + 3] = mid + 1
            n = _svt_count(t, b[0], b[1], b[2], b[3], b[4], b[5])
            if n > 0:
                hi = mid
            else:
                lo = mid + 1
        b[ax + 3] = keep_hi
        b[ax] = lo
        keep_lo = lo
        # high face: largest c with count([c, b[ax+3])) > 0
        lo = keep_lo
        hi = keep_hi - 1
        while lo < hi:
            mid = (lo + hi + 1) // 2
            b[ax] = mid
            n = _svt_count(t, b[0], b[1], b[2], b[3], b[4], b[5])
            if n > 0:
                lo = mid
            else:
                hi = mid - 1
        b[ax] = keep_lo
        b[ax + 3] = lo + 1


@njit(cache=True)
def tight_box(svt, bslot, bcount, bbox, q, out, work):
    """Tight box of the occupied cells in box ``q``.

    Writes the tight box into ``out`` (6 ints) and returns True when ``q`` holds an
    occupied cell. ``work`` is scratch of 6 ints.
    """
    S = SVT_BRICK
    found = False
    out[0] = 1 << 30
    out[1] = 1 << 30
    out[2] = 1 << 30
    out[3] = -1
    out[4] = -1
    out[5] = -1
    for bz in range(q[2] // S, (q[5] - 1) // S + 1):
        for by in range(q[1] // S, (q[4] - 1) // S + 1):
            for bx in range(q[0] // S, (q[3] - 1) // S + 1):
                n = bcount[bz, by, bx]
                if n == 0:
                    continue
                # intersection of the query with the brick's tight box
                inside = True
                empty = False
                for a in range(3):
                    lo = max(q[a], bbox[bz, by, bx, a])
                    hi = min(q[a + 3], bbox[bz, by, bx, a + 3])
                    if lo >= hi:
                        empty = True
                        break
                    if lo != bbox[bz, by, bx, a] or hi != bbox[bz, by, bx, a + 3]:
                        inside = False
                    work[a] = lo
                    work[a + 3] = hi
                if empty:
                    continue
                if not inside:
                    bb_vol = np.int64(1)
                    for a in range(3):
                        bb_vol *= bbox[bz, by, bx, a + 3] - bbox[bz, by, bx, a]
                    if n != bb_vol:  # not fully occupied: search the SVT
                        t = svt[bslot[bz, by, bx]]
                        ox = bx * S
                        oy = by * S
                        oz = bz * S
                        work[0] -= ox
                        work[3] -= ox
                        work[1] -= oy
                        work[4] -= oy
                        work[2] -= oz
                        work[5] -= oz
                        if _svt_count(t, work[0], work[1], work[2], work[3], work[4], work[5]) == 0:
                            continue
                        _shrink(t, work)
                        work[0] += ox
                        work[3] += ox
                        work[1] += oy
                        work[4] += oy
                        work[2] += oz
                        work[5] += oz
                found = True
                for a in range(3):
                    out[a] = min(out[a], work[a])
                    out[a + 3] = max(out[a + 3], work[a + 3])
    return found


@njit(cache=True)
def box_count(svt, bslot, bcount, bbox, q):
    """Occupied cells in box ``q`` (O(#bricks) SVT look-ups)."""
    S = SVT_BRICK
    total = np.int64(0)
    for bz in range(q[2] // S, (q[5] - 1) // S + 1):
        for by in range(q[1] // S, (q[4] - 1) // S + 1):
            for bx in range(q[0] // S, (q[3] - 1) // S + 1):
                if bcount[bz, by, bx] == 0:
                    continue
                x0 = max(q[0], bx * S) - bx * S
                y0 = max(q[1], by * S) - by * S
                z0 = max(q[2], bz * S) - bz * S
                x1 = min(q[3], bx * S + S) - bx * S
                y1 = min(q[4], by * S + S) - by * S
                z1 = min(q[5], bz * S + S) - bz * S
                total += _svt_count(svt[bslot[bz, by, bx]], x0, y0, z0, x1, y1, z1)
    return total



@njit(cache=True, parallel=True)
def block_occupancy(svt, bslot, bcount, block, out):
    """``out[gz, gy, gx] = 1`` where the ``block``^3 cells of grid cell ``g`` hold an
    occupied cell (``block`` divides 32): the hybrid grid, read off the SVTs."""
    S = SVT_BRICK
    ngz, ngy, ngx = out.shape
    for gz in prange(ngz):
        for gy in range(ngy):
            for gx in range(ngx):
                z0 = gz * block
                y0 = gy * block
                x0 = gx * block
                bz = z0 // S
                by = y0 // S
                bx = x0 // S
                if bcount[bz, by, bx] == 0:
                    out[gz, gy, gx] = 0
                    continue
                t = svt[bslot[bz, by, bx]]
                lx = x0 - bx * S
                ly = y0 - by * S
                lz = z0 - bz * S
                n = _svt_count(t, lx, ly, lz, lx + block, ly + block, lz + block)
                out[gz, gy, gx] = 1 if n > 0 else 0
