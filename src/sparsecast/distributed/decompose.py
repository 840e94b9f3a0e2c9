"""Cutting a volume into pieces: the top levels of a k-d tree over its non-empty bricks.

A piece is a box of whole bricks; the pieces tile the brick grid (no gaps: a TF that
makes background visible still finds every sample in some piece). Each split cuts the
longest axis of its box on the brick plane that best balances the **non-empty** bricks
on either side (not the volume: a sparse field's work is where its bricks are), in the
ratio of the pieces each side gets, so any piece count works, not only powers of two.

The same tree orders the pieces for compositing: at every split the side the camera is
on comes first (orthographic: the side the rays enter first), which is a front-to-back
order for every ray, perspective or orthographic, because axis-aligned cuts form a
binary space partition.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError

__all__ = ["PieceTree", "decompose"]


@dataclass(frozen=True)
class PieceTree:
    """Pieces of a brick grid and the k-d tree that cut them.

    Attributes
    ----------
    brick_size : int
        Cells per brick edge ``B``.
    grid : (3,) tuple of int
        Brick counts ``(nbz, nby, nbx)``.
    boxes : ndarray of int64, shape (n, 2, 3)
        Piece ``p`` holds bricks ``boxes[p, 0] <= (bx, by, bz) < boxes[p, 1]`` (x, y, z order).
    weights : ndarray of int64, shape (n,)
        Non-empty bricks in each piece.
    nodes : list of tuple
        Node ``i`` is ``("leaf", piece)`` or ``("split", axis, plane, low, high)`` with
        ``axis`` 0/1/2 for x/y/z, ``plane`` the brick index of the cut and ``low``/``high``
        the node ids of the two sides; node 0 is the root.
    """

    brick_size: int
    grid: tuple[int, int, int]
    boxes: np.ndarray
    weights: np.ndarray
    nodes: list

    @property
    def count(self) -> int:
        """Number of pieces."""
        return int(self.boxes.shape[0])

    def voxel_box(self, piece: int, shape: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
        """Index-space box ``(lo, hi)`` (x, y, z) of a piece's cells, clamped to the volume."""
        nz, ny, nx = shape
        top = np.array([nx - 1, ny - 1, nz - 1], np.int64)
        b = self.boxes[piece]
        return np.minimum(b[0] * self.brick_size, top), np.minimum(b[1] * self.brick_size, top)

    def order(self, near_low) -> list[int]:
        """Pieces front to back: ``near_low(axis, plane)`` says whether the side below the
        cut at brick ``plane`` of ``axis`` comes first for the camera."""
        out: list[int] = []
        stack = [0]
        while stack:
            node = self.nodes[stack.pop()]
            if node[0] == "leaf":
                out.append(node[1])
                continue
            _, axis, plane, low, high = node
            first, second = (low, high) if near_low(axis, plane) else (high, low)
            stack.append(second)
            stack.append(first)
        return out

    def reduction(self, near_low):
        """The compositing tree for the camera: a piece id, or ``(near, far)`` of subtrees."""
        def walk(i):
            node = self.nodes[i]
            if node[0] == "leaf":
                return node[1]
            _, axis, plane, low, high = node
            a, b = walk(low), walk(high)
            return (a, b) if near_low(axis, plane) else (b, a)
        return walk(0)


def decompose(occupied: np.ndarray, pieces: int, brick_size: int) -> PieceTree:
    """Cut the brick grid into ``pieces`` boxes balanced by non-empty bricks.

    Parameters
    ----------
    occupied : ndarray of bool, shape (nbz, nby, nbx)
        Bricks that hold anything (not entirely background).
    pieces : int
        Pieces wanted, >= 1. Fewer come back only when the grid has fewer bricks.
    brick_size : int
        ``B`` of the grid, recorded in the tree.

    Returns
    -------
    PieceTree
    """
    if isinstance(pieces, bool) or not isinstance(pieces, (int, np.integer)) or pieces < 1:
        raise ParameterError(f"pieces: expected a whole number >= 1, got {pieces!r}")
    occ = np.asarray(occupied, bool)
    if occ.ndim != 3:
        raise ParameterError(f"occupied: expected a 3-D brick grid, got shape {occ.shape}")
    # Per-axis prefix counts would need the box's other two extents; a 3-D summed table
    # answers "non-empty bricks in a box" in O(1) for every candidate plane.
    sat = np.zeros(tuple(n + 1 for n in occ.shape), np.int64)
    sat[1:, 1:, 1:] = occ.astype(np.int64).cumsum(0).cumsum(1).cumsum(2)

    def count(lo, hi) -> int:  # lo, hi in (x, y, z), half-open, brick units
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        return int(sat[z1, y1, x1] - sat[z0, y1, x1] - sat[z1, y0, x1] - sat[z1, y1, x0]
                   + sat[z0, y0, x1] + sat[z0, y1, x0] + sat[z1, y0, x0] - sat[z0, y0, x0])

    nodes: list = []
    boxes: list = []
    weights: list = []

    def build(lo, hi, n) -> int:
        me = len(nodes)
        nodes.append(None)
        extent = [hi[a] - lo[a] for a in range(3)]
        axes = [a for a in sorted(range(3), key=lambda a: -extent[a]) if extent[a] >= 2]
        if n == 1 or not axes:
            nodes[me] = ("leaf", len(boxes))
            boxes.append((tuple(lo), tuple(hi)))
            weights.append(count(lo, hi))
            return me
        axis = axes[0]
        total = count(lo, hi)
        cross = int(np.prod(extent)) // extent[axis]
        best = None
        for plane in range(lo[axis] + 1, hi[axis]):
            # Each side gets at most one piece per brick it holds, at least one piece.
            low_bricks = (plane - lo[axis]) * cross
            high_bricks = (hi[axis] - plane) * cross
            n_low = min(max(n // 2, n - high_bricks, 1), low_bricks, n - 1)
            cut = list(hi)
            cut[axis] = plane
            if total:
                err = abs(count(lo, cut) * n - total * n_low)
            else:  # nothing non-empty: balance the volume instead
                err = abs((plane - lo[axis]) * n - extent[axis] * n_low)
            if best is None or err < best[0]:
                best = (err, plane, n_low)
        _, best, n_low = best
        mid_hi = list(hi)
        mid_hi[axis] = best
        mid_lo = list(lo)
        mid_lo[axis] = best
        low = build(list(lo), mid_hi, n_low)
        high = build(mid_lo, list(hi), n - n_low)
        nodes[me] = ("split", axis, best, low, high)
        return me

    nbz, nby, nbx = occ.shape
    build([0, 0, 0], [nbx, nby, nbz], min(int(pieces), occ.size))
    return PieceTree(int(brick_size), (nbz, nby, nbx), np.array(boxes, np.int64).reshape(-1, 2, 3),
                     np.array(weights, np.int64), nodes)
