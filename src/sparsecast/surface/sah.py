"""The parallel binned-SAH build: the top of the tree on one thread, its subtrees on all of them.

:func:`build_sah` splits the root's references until every pending node holds at
most ``m / (threads * TASKS_PER_THREAD)`` of them (one thread: each split is a
pass over the node's references, so the top levels are a small share of the
work), then hands those nodes to a thread pool, largest first, where the
``nogil`` kernel :func:`._bvh_build_kernels.build_range` builds each subtree
into its own range of node slots. Subtrees own disjoint ranges of the references
and of the slots, so the threads share nothing; the tree does not depend on the
thread count (every node is split by the same rule wherever it is built).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from ._bvh_build_kernels import NODE_BOX, build_range, flatten_binary, prim_refs

__all__ = ["BuildTree", "build_sah", "TASKS_PER_THREAD", "PARALLEL_MIN"]

#: subtree tasks per thread: enough that threads finishing early find more work
TASKS_PER_THREAD = 8
#: fewer references than this are built on one thread (task overhead would dominate)
PARALLEL_MIN = 8192


@dataclass(frozen=True)
class BuildTree:
    """A binary BVH in the build layout (see :mod:`._bvh_build_kernels`).

    Attributes
    ----------
    bounds : (cap, 2, 3) float32
    first, count : (cap,) int32
        Children ``first, first + 1`` of an inner node (``count == 0``), or the
        leaf's references ``ids[first : first + count]``; unused slots have
        ``first == -1``.
    ids : (m,) int32
        Primitive of each reference, in leaf order.
    depth : int
    threads : int
        Threads the subtrees were built on.
    """

    bounds: np.ndarray
    first: np.ndarray
    count: np.ndarray
    ids: np.ndarray
    depth: int
    threads: int

    def flatten(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The compact depth-first binary layout ``(node_bounds, node_child, node_count)``."""
        used = int(np.count_nonzero(self.first >= 0))
        return flatten_binary(self.bounds, self.first, self.count, max(used, 1))


def build_sah(bmin: np.ndarray, bmax: np.ndarray, max_leaf: int = 4, bins: int = 16,
              threads: int | None = None, prims: np.ndarray | None = None) -> BuildTree:
    """Binned-SAH BVH over ``m >= 1`` primitive boxes ``bmin``, ``bmax`` (m, 3).

    Parameters
    ----------
    max_leaf : int
        Nodes of at most this many primitives are leaves (the SAH may stop earlier,
        at up to ``4 * max_leaf``).
    bins : int
        SAH bins per axis.
    threads : int, optional
        Default ``numba.get_num_threads()``.
    prims : (m,) int32, optional
        The primitive each box stands for (default: box ``i`` is primitive ``i``); several
        boxes may name one primitive (:mod:`.presplit`'s references), and ``ids`` then
        names it in the leaf of each.
    """
    box, ids, root = prim_refs(bmin, bmax)
    if prims is not None:
        ids[:] = prims
    m = len(ids)
    cap = max(2 * m - 1, 1)
    bounds = np.empty((cap, 2, 3), np.float32)
    first = np.full(cap, -1, np.int32)
    count = np.zeros(cap, np.int32)
    threads = max(1, int(numba.get_num_threads() if threads is None else threads))
    if threads == 1 or m < PARALLEL_MIN:
        stop = -1
    else:
        stop = max(m // (threads * TASKS_PER_THREAD), 4 * max_leaf + 1)
    n_task_max = m // (max_leaf + 1) + 2
    t_node = np.empty(n_task_max, np.int32)
    t_s = np.empty(n_task_max, np.int32)
    t_e = np.empty(n_task_max, np.int32)
    t_d = np.empty(n_task_max, np.int32)
    t_box = np.empty((n_task_max, NODE_BOX), np.float32)
    n_top, depth, n_tasks = build_range(box, ids, bounds, first, count, 0, 0, m, root, 1, 1, max_leaf, bins,
                                        stop, t_node, t_s, t_e, t_box, t_d)
    if n_tasks:
        sizes = t_e[:n_tasks] - t_s[:n_tasks]
        order = np.argsort(-sizes, kind="stable")
        # Each task's subtree takes at most 2 m_i - 2 slots below its root.
        base = n_top + np.concatenate([[0], np.cumsum(2 * sizes[order] - 2)[:-1]])
        dummy_i = np.empty(0, np.int32)
        dummy_b = np.empty((0, NODE_BOX), np.float32)
        with ThreadPoolExecutor(max_workers=min(threads, n_tasks), thread_name_prefix="sparsecast-bvh") as pool:
            futures = [pool.submit(build_range, box, ids, bounds, first, count, int(t_node[k]), int(t_s[k]),
                                   int(t_e[k]), t_box[k], int(b), int(t_d[k]), max_leaf, bins, -1,
                                   dummy_i, dummy_i, dummy_i, dummy_b, dummy_i)
                       for k, b in zip(order, base)]
            depth = max([depth] + [f.result()[1] for f in futures])
    return BuildTree(bounds, first, count, ids, int(depth), threads if n_tasks else 1)
