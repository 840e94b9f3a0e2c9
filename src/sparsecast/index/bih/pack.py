"""Fixed-point packing of BIH nodes into 64-bit words and the tree-chunk layout (Numba kernels).

The word format is described in :mod:`.build`; :mod:`.traversal` reads it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .construct import LEAF

#: fixed-point plane codes: 0x4000 is 0 and 0xC000 is 1 in normalised space
Q_ZERO, Q_ONE = 0x4000, 0xC000
Q_NEG_INF, Q_POS_INF = 0x0000, 0xFFFF
DENSITY_MAX = (1 << 14) - 1
GRAD_ZERO = 0x8000
GRAD_MAX = 0x7FFF


@njit(cache=True, inline="always")
def quantize_plane(x, lo, ext, up):
    """16-bit code of plane ``x`` in the frame ``[lo, lo + ext]``, rounded outward
    (``up``: towards +inf, for upper bounds), so that boxes only grow; +-inf map to
    0xFFFF / 0x0000 and finite planes to ``1..0xFFFE``."""
    if x == math.inf:
        return Q_POS_INF
    if x == -math.inf:
        return Q_NEG_INF
    u = (x - lo) / ext * (Q_ONE - Q_ZERO) + Q_ZERO
    q = math.ceil(u) if up else math.floor(u)
    return int(min(max(q, 1.0), float(Q_POS_INF - 1)))


@njit(cache=True, inline="always")
def dequantize_plane(q, lo, step):
    """Plane position of code ``q`` (``step = ext / 0x8000``)."""
    if q == Q_POS_INF:
        return math.inf
    if q == Q_NEG_INF:
        return -math.inf
    return lo + (q - Q_ZERO) * step


@njit(cache=True)
def pack_nodes(kind, child, plane, density, gradient, leaf_first, leaf_count, frame_lo, frame_ext,
               grad_scale, particles, slot_of, field_of, out):
    """Encode every node into one 64-bit word (stored as int64; see :mod:`.bih`).

    ``slot_of[i]`` is node ``i``'s position in ``out``; ``field_of[i]`` its 30-bit
    child field (computed by the layout). Inner: bits 62-63 axis, 32-61 child
    field, 16-31 plane 1, 0-15 plane 0. Leaf: bits 62-63 = 3 and either the density
    (14 bits, 48-61) and gradient (x: 0-15, y: 16-31, z: 32-47), or, for particle
    trees, the first element (32-61) and count (0-31).
    """
    for i in range(kind.shape[0]):
        k = kind[i]
        if k == LEAF:
            w = np.int64(LEAF) << 62
            if particles:
                w |= np.int64(leaf_first[i]) << 32
                w |= np.int64(leaf_count[i])
            else:
                dq = int(round(min(max(density[i], 0.0), 1.0) * DENSITY_MAX))
                w |= np.int64(dq) << 48
                for a in range(3):
                    g = gradient[i, a] / grad_scale if grad_scale > 0.0 else 0.0
                    gq = int(round(min(max(g, -1.0), 1.0) * GRAD_MAX)) + GRAD_ZERO
                    w |= np.int64(gq) << (16 * a)
        else:
            a = k
            if child[i, 1] >= 0:  # two children: left upper bound, right lower bound
                q0 = quantize_plane(plane[i, 0], frame_lo[a], frame_ext[a], True)
                q1 = quantize_plane(plane[i, 1], frame_lo[a], frame_ext[a], False)
            elif plane[i, 0] == -math.inf:  # basic, only the left child: its upper bound
                q0 = quantize_plane(plane[i, 1], frame_lo[a], frame_ext[a], True)
                q1 = Q_POS_INF  # the empty right child's invalid plane
            elif plane[i, 1] == math.inf:  # basic, only the right child: its lower bound
                q0 = Q_NEG_INF  # the empty left child's invalid plane
                q1 = quantize_plane(plane[i, 0], frame_lo[a], frame_ext[a], False)
            else:  # elaborate single child: [lower, upper]
                q0 = quantize_plane(plane[i, 0], frame_lo[a], frame_ext[a], False)
                q1 = quantize_plane(plane[i, 1], frame_lo[a], frame_ext[a], True)
            w = (np.int64(a) << 62) | (np.int64(field_of[i]) << 32) | (np.int64(q1) << 16) | np.int64(q0)
        out[slot_of[i]] = w


@njit(cache=True)
def preorder_fields(child, field_of):
    """Child fields of the pre-order layout: the right child's index for two
    children (the left one follows its parent), ``i + 1`` for a single child."""
    for i in range(child.shape[0]):
        if child[i, 0] < 0:
            field_of[i] = 0
        elif child[i, 1] >= 0:
            field_of[i] = child[i, 1]
        else:
            field_of[i] = i + 1


@njit(cache=True)
def chunk_layout(child, chunk_depth, slot_of, field_of):
    """Tree-chunk layout: siblings stored as an aligned pair, chunks of
    ``chunk_depth`` levels of sibling pairs stored together, chunks depth first.

    Slot 0 holds the root (slot 1 is padding); every group of children starts at
    an even slot; a single child occupies the first slot of its pair, and its
    parent's field has bit 0 set. Returns the number of slots.
    """
    m = child.shape[0]
    # chunk roots: pending groups (a parent whose children start a new chunk)
    pending = np.empty(m + 1, np.int64)
    level = np.empty(m + 1, np.int64)
    nxt = np.empty(m + 1, np.int64)
    slot_of[0] = 0
    next_slot = 2
    np_ = 0
    if child[0, 0] >= 0:
        pending[0] = 0
        np_ = 1
    while np_ > 0:
        np_ -= 1
        # breadth first over chunk_depth levels of groups below this parent
        level[0] = pending[np_]
        nl = 1
        for _ in range(chunk_depth):
            nn = 0
            for p in range(nl):
                parent = level[p]
                c0 = child[parent, 0]
                c1 = child[parent, 1]
                s = next_slot
                next_slot += 2
                slot_of[c0] = s
                if c1 >= 0:
                    slot_of[c1] = s + 1
                    field_of[parent] = s
                else:
                    field_of[parent] = s | 1
                for c in (c0, c1):
                    if c >= 0 and child[c, 0] >= 0:
                        nxt[nn] = c
                        nn += 1
            for p in range(nn):
                level[p] = nxt[p]
            nl = nn
            if nl == 0:
                break
        # groups below the chunk start chunks of their own (reverse: depth first)
        for p in range(nl - 1, -1, -1):
            pending[np_] = level[p]
            np_ += 1
    for i in range(m):
        if child[i, 0] < 0:
            field_of[i] = 0
    return next_slot
