"""Wald's iterative range tree (IRT): range-maximum queries over a 1-D array in O(log n).

I. Wald, *Computing Minima and Maxima of Subarrays*, Ray Tracing Gems (2019), ch. 21.
Used here to answer "maximum opacity over transfer-function table entries
``[lo, hi]``" — an alternative to the O(1) prefix count behind
:meth:`TransferFunction.is_empty <sparsecast.transfer.TransferFunction.is_empty>` that
also yields the *value* of the maximum (useful e.g. for opacity-bounded step sizes).
No renderer uses it: it lives in the benchmark package, where :mod:`.irt` times it
against the prefix count.

Layout
------
All levels live in ONE flat array ``flat``. Level 0 is a copy of the input
(``n`` values); level ``L+1`` holds ``ceil(n_L / 2)`` values, entry ``i`` being
``max(level_L[2i], level_L[2i+1])`` (or ``level_L[2i]`` alone for the last entry of
an odd-sized level). Levels are built until a level has a single entry (the global
maximum). ``offsets[L]`` / ``sizes[L]`` (int64) locate level ``L`` in ``flat``, so
Numba kernels take three arrays and no Python object.

Query rule (inclusive ``[lo, hi]`` at level 0)
----------------------------------------------
::

    while lo <= hi:
        if lo is odd:  result = max(result, level[lo]);  lo += 1   # lo is a right child
        if hi is even: result = max(result, level[hi]);  hi -= 1   # hi is a left child
        lo //= 2; hi //= 2; level += 1                            # step to the parents

After the two boundary fix-ups ``lo`` is even and ``hi`` odd (or ``lo > hi``), so
``[lo, hi]`` is a union of whole sibling pairs and is covered exactly by the parent
range ``[lo/2, hi/2]``. ``hi`` may become ``-1``; floor division keeps it ``-1``
and the loop ends. Each level costs O(1), hence O(log n) per query; at the top
level (one entry) ``lo == hi == 0`` is consumed by the ``hi`` rule, so the loop
never steps past the last level.
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit, prange

from ..errors import ParameterError
from ..kernels.classify import entry_span

__all__ = [
    "RangeMaxTree",
    "build_levels",
    "range_max",
    "range_max_many",
    "level_layout",
    "opacity_range_tree",
    "classify_ranges_irt",
    "classify_irt",
    "is_empty_irt",
]


# -- kernels ----------------------------------------------------------------
@njit(cache=True)
def build_levels(values, out, offsets, sizes):
    """Fill ``out`` with all levels of the tree over ``values`` (bottom-up pairwise max).

    Parameters
    ----------
    values : ndarray, shape (n,)
        Level-0 values.
    out : ndarray, shape (offsets[-1] + sizes[-1],)
        Flat level storage, written in place.
    offsets, sizes : ndarray of int64
        Level layout from :func:`level_layout`.
    """
    n0 = sizes[0]
    for i in range(n0):
        out[i] = values[i]
    for lvl in range(1, sizes.shape[0]):
        src = offsets[lvl - 1]
        m = sizes[lvl - 1]
        dst = offsets[lvl]
        for i in range(sizes[lvl]):
            a = out[src + 2 * i]
            if 2 * i + 1 < m:
                b = out[src + 2 * i + 1]
                if b > a:
                    a = b
            out[dst + i] = a


@njit(cache=True, inline="always")
def range_max(flat, offsets, sizes, lo, hi):
    """Maximum of level-0 entries ``lo..hi`` (inclusive) of an IRT.

    No bounds checks: the caller guarantees ``0 <= lo`` and ``hi < sizes[0]``.
    For ``lo > hi`` the range is empty and the result is ``-inf``.
    Inlined into calling kernels (``inline="always"``), so renderers and indices
    can call it per node / per brick without call overhead.
    """
    result = -np.inf
    lvl = 0
    while lo <= hi:
        off = offsets[lvl]
        if lo & 1:
            v = flat[off + lo]
            if v > result:
                result = v
            lo += 1
        if (hi & 1) == 0:
            v = flat[off + hi]
            if v > result:
                result = v
            hi -= 1
        lo = lo // 2
        hi = hi // 2  # -1 // 2 == -1: terminates
        lvl += 1
    return result


@njit(cache=True, parallel=True)
def range_max_many(flat, offsets, sizes, lo, hi, out):
    """``out[i] = range_max(flat, offsets, sizes, lo[i], hi[i])`` in parallel.

    ``lo`` and ``hi`` are int64 arrays already clamped to ``[0, sizes[0] - 1]``;
    entries with ``lo > hi`` give ``-inf``.
    """
    for i in prange(lo.shape[0]):
        out[i] = range_max(flat, offsets, sizes, lo[i], hi[i])


@njit(cache=True, parallel=True)
def classify_ranges_irt(flat, offsets, sizes, v_lo, scale, vmin, vmax, out):
    """IRT twin of :func:`sparsecast.kernels.classify.classify_ranges`.

    ``out[i] = max opacity over the table entries that values in [vmin[i], vmax[i]]
    touch > 0``, the entries coming from the same
    :func:`~sparsecast.kernels.classify.entry_span` the prefix-count kernel uses
    (``flat`` is an IRT over the opacity column; ``sizes[0]`` is the table size).
    Inverted spans (``first > last``) count as empty.
    """
    n = sizes[0]
    for i in prange(vmin.shape[0]):
        first, last = entry_span(v_lo, scale, n, vmin[i], vmax[i])
        out[i] = range_max(flat, offsets, sizes, first, last) > 0


def level_layout(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Offsets and sizes (int64) of the levels of an IRT over ``n >= 1`` values."""
    if n < 1:
        raise ParameterError(f"values: expected at least one value, got {n}")
    sizes = [n]
    while sizes[-1] > 1:
        sizes.append((sizes[-1] + 1) // 2)
    sizes_a = np.array(sizes, dtype=np.int64)
    offsets = np.zeros_like(sizes_a)
    offsets[1:] = np.cumsum(sizes_a)[:-1]
    return offsets, sizes_a


# -- object -----------------------------------------------------------------
class RangeMaxTree:
    """Iterative range tree (Wald 2019) answering range-maximum queries in O(log n).

    Parameters
    ----------
    values : array_like, shape (n,)
        Finite real values, ``n >= 1`` (e.g. a TF table's opacity column). float32
        input is stored as float32, anything else as float64.

    Attributes
    ----------
    flat : ndarray, shape (total,)
        All levels, level 0 (a copy of ``values``) first. Read-only.
    offsets, sizes : ndarray of int64, shape (levels,)
        Start and length of each level in ``flat``. Read-only.
    size : int
        Number of level-0 entries ``n``.
    build_ms : float
        Wall time of the build (layout, allocation and the level kernel), in ms.

    Examples
    --------
    >>> t = RangeMaxTree([0.0, 0.5, 0.2, 0.9, 0.1])
    >>> t.query(0, 2), t.query(2, 4), t.query(4, 4)
    (0.5, 0.9, 0.1)
    """

    def __init__(self, values) -> None:
        t0 = time.perf_counter()
        v = np.asarray(values)
        if v.ndim != 1:
            raise ParameterError(f"values: expected a 1-D array, got shape {v.shape}")
        if v.size < 1:
            raise ParameterError("values: expected at least one value, got an empty array")
        if not np.issubdtype(v.dtype, np.number) or np.issubdtype(v.dtype, np.complexfloating):
            raise ParameterError(f"values: expected real numbers, got dtype {v.dtype}")
        dtype = np.float32 if v.dtype == np.float32 else np.float64
        v = np.ascontiguousarray(v, dtype=dtype)
        if not np.all(np.isfinite(v)):
            raise ParameterError("values: expected finite numbers, found NaN or Inf")
        offsets, sizes = level_layout(int(v.shape[0]))
        flat = np.empty(int(offsets[-1] + sizes[-1]), dtype=dtype)
        build_levels(v, flat, offsets, sizes)
        for a in (flat, offsets, sizes):
            a.flags.writeable = False
        self.flat = flat
        self.offsets = offsets
        self.sizes = sizes
        self.size = int(sizes[0])
        self.build_ms = (time.perf_counter() - t0) * 1e3

    @property
    def levels(self) -> int:
        """Number of levels, including level 0 and the single-entry top level."""
        return int(self.sizes.shape[0])

    @property
    def nbytes(self) -> int:
        """Bytes of the flat level array plus the layout arrays."""
        return int(self.flat.nbytes + self.offsets.nbytes + self.sizes.nbytes)

    def level(self, i: int) -> np.ndarray:
        """Read-only view of level ``i`` (0 = the input values)."""
        if not 0 <= i < self.levels:
            raise ParameterError(f"level: expected 0..{self.levels - 1}, got {i}")
        o, s = int(self.offsets[i]), int(self.sizes[i])
        return self.flat[o:o + s]

    def query(self, lo: int, hi: int) -> float:
        """Maximum of entries ``lo..hi`` (inclusive), indices clamped to ``[0, n-1]``.

        Raises
        ------
        ParameterError
            If ``lo > hi`` or an index is not an integer.
        """
        try:
            lo_i, hi_i = int(np.asarray(lo).item()), int(np.asarray(hi).item())
            if lo_i != lo or hi_i != hi:
                raise TypeError
        except (TypeError, ValueError):
            raise ParameterError(f"lo, hi: expected integer indices, got {lo!r}, {hi!r}") from None
        if lo_i > hi_i:
            raise ParameterError(f"lo, hi: expected lo <= hi, got lo={lo_i} > hi={hi_i}")
        n = self.size
        lo_i = min(max(lo_i, 0), n - 1)
        hi_i = min(max(hi_i, 0), n - 1)
        return float(range_max(self.flat, self.offsets, self.sizes, lo_i, hi_i))

    def query_many(self, lo, hi) -> np.ndarray:
        """Vectorised :meth:`query` (parallel Numba kernel).

        Parameters
        ----------
        lo, hi : array_like of int
            Inclusive index ranges, broadcast together; clamped to ``[0, n-1]``.

        Returns
        -------
        ndarray
            Maxima, same dtype as :attr:`flat`, shape of the broadcast inputs.

        Raises
        ------
        ParameterError
            If any ``lo > hi`` or the indices are not integers.
        """
        lo_a, hi_a = np.broadcast_arrays(np.asarray(lo), np.asarray(hi))
        for name, a in (("lo", lo_a), ("hi", hi_a)):
            if a.size and not np.issubdtype(a.dtype, np.integer):
                raise ParameterError(f"{name}: expected integer indices, got dtype {a.dtype}")
        bad = lo_a > hi_a
        if np.any(bad):
            k = int(np.flatnonzero(bad.ravel())[0])
            raise ParameterError(
                f"lo, hi: expected lo <= hi everywhere, got lo={lo_a.ravel()[k]} > hi={hi_a.ravel()[k]} "
                f"at flat position {k}"
            )
        return self._query_clamped(lo_a, hi_a)

    def _query_clamped(self, lo_a: np.ndarray, hi_a: np.ndarray) -> np.ndarray:
        """Kernel call without the ``lo <= hi`` check (``lo > hi`` gives ``-inf``)."""
        shape = lo_a.shape
        n = self.size
        lo_c = np.clip(lo_a.ravel(), 0, n - 1).astype(np.int64)
        hi_c = np.clip(hi_a.ravel(), 0, n - 1).astype(np.int64)
        out = np.empty(lo_c.shape[0], dtype=self.flat.dtype)
        if lo_c.shape[0]:
            range_max_many(self.flat, self.offsets, self.sizes, lo_c, hi_c, out)
        return out.reshape(shape)

    def __repr__(self) -> str:
        return (f"RangeMaxTree(size={self.size}, levels={self.levels}, dtype={self.flat.dtype}, "
                f"nbytes={self.nbytes}, build_ms={self.build_ms:.3f})")


# -- transfer-function helpers ---------------------------------------------------
def opacity_range_tree(tf) -> RangeMaxTree:
    """IRT over the opacity column ``tf.table[:, 3]`` of a :class:`TransferFunction`."""
    return RangeMaxTree(tf.table[:, 3])


def _check_pair(tree: RangeMaxTree, tf) -> None:
    if tree.size != tf.table_size:
        raise ParameterError(
            f"tree: built over {tree.size} entries, but the transfer function has "
            f"table_size {tf.table_size}; build it with opacity_range_tree(tf)"
        )


def classify_irt(tree: RangeMaxTree, tf, vmin, vmax) -> np.ndarray:
    """IRT version of :meth:`TransferFunction.classify`: True where ``[vmin, vmax]`` is *non-empty*.

    Data values map to table entries with the same
    :func:`sparsecast.kernels.classify.entry_span` that ``tf.classify`` (and
    ``tf._entry_span``) use: floor/ceil of the clipped table positions of the
    range widened by ``SPAN_MARGIN`` of its span. A region is non-empty iff the maximum opacity over
    those entries is > 0, so for ``vmin <= vmax`` the answer equals
    ``tf.classify(vmin, vmax)`` element for element.

    Parameters
    ----------
    tree : RangeMaxTree
        From :func:`opacity_range_tree` of the same ``tf``.
    tf : TransferFunction
    vmin, vmax : array_like
        Per-region value ranges (broadcast together), finite.

    Returns
    -------
    ndarray of bool
        Shape of the broadcast inputs.

    Notes
    -----
    Inverted ranges (``vmin > vmax``) are reported empty here; ``tf.classify``
    answers them from a negative prefix difference, so the two may differ there.
    """
    _check_pair(tree, tf)
    lo, hi = np.broadcast_arrays(np.asarray(vmin, np.float64), np.asarray(vmax, np.float64))
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ParameterError("vmin/vmax: expected finite values, found NaN or Inf")
    shape = lo.shape
    lo = np.ascontiguousarray(lo).ravel()
    hi = np.ascontiguousarray(hi).ravel()
    out = np.empty(lo.shape[0], np.bool_)
    if lo.shape[0]:
        classify_ranges_irt(tree.flat, tree.offsets, tree.sizes, float(tf.value_range[0]), float(tf.scale),
                            lo, hi, out)
    return out.reshape(shape)


def is_empty_irt(tree: RangeMaxTree, tf, vmin, vmax):
    """IRT version of :meth:`TransferFunction.is_empty`: True where ``[vmin, vmax]`` is *empty*.

    The exact negation of :func:`classify_irt` (and so of ``tf.classify``).
    Scalar inputs give a Python ``bool`` (like ``tf.is_empty``); arrays a boolean
    array.
    """
    empty = ~classify_irt(tree, tf, vmin, vmax)
    return bool(empty) if empty.ndim == 0 else empty
