"""Iterative range tree (IRT) vs. prefix count on transfer-function tables.

:func:`irt_build_times` measures, per table size, the IRT build over the opacity
column and the cost of classifying a batch of value ranges through the IRT and
through :meth:`TransferFunction.classify` (prefix count). Benchmarks are not tests:
the records are for ``sparsecast bench`` to print and write, never to assert on.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from .range_tree import RangeMaxTree, classify_irt, opacity_range_tree
from ..transfer import TransferFunction
from .timing import median_ms

__all__ = ["irt_build_times"]

#: Number of (vmin, vmax) ranges classified per query measurement.
N_QUERIES = 32768


def _bench_tf(n: int) -> TransferFunction:
    """A TF with transparent gaps and a few opaque bumps (deterministic)."""
    pts = [
        (0.00, 0, 0, 0, 0.0), (0.20, 0, 0, 0, 0.0), (0.25, 1, 0, 0, 0.3), (0.30, 1, 0, 0, 0.0),
        (0.55, 0, 1, 0, 0.0), (0.60, 0, 1, 0, 0.8), (0.70, 0, 1, 0, 0.0),
        (0.90, 0, 0, 1, 0.0), (1.00, 0, 0, 1, 1.0),
    ]
    return TransferFunction(pts, (0.0, 1.0), table_size=n, name="irt-bench")


def irt_build_times(
    sizes: Iterable[int] = (256, 512, 1024, 2048, 4096),
    repeat: int = 20,
    *,
    n_queries: int = N_QUERIES,
    seed: int = 0,
) -> list[dict[str, Any]]:
    """Time IRT build and range classification against the prefix count.

    Parameters
    ----------
    sizes : iterable of int
        TF table sizes (256..4096).
    repeat : int
        Timed runs per measurement; the median is reported. One untimed warm-up run
        (JIT compilation / cache load) precedes every measurement.
    n_queries : int
        ``(vmin, vmax)`` ranges per query measurement (default 32768).
    seed : int
        Seed for the random ranges (uniform over slightly more than the TF range).

    Returns
    -------
    list of dict
        Per size three records, all with ``method``, ``phase``, ``table_size``,
        ``ms`` (median), ``ms_runs`` and ``bytes``:

        * ``phase="irt_build"``: ``RangeMaxTree`` over ``tf.table[:, 3]``; ``bytes`` =
          :attr:`RangeMaxTree.nbytes`.
        * ``phase="irt_query"``: :func:`classify_irt` of ``n_queries`` ranges
          (``queries`` field), including the value-to-entry mapping.
        * ``phase="prefix_query"``: ``tf.classify`` of the same ranges; ``bytes`` =
          the prefix-count array.

        ``irt_query`` records also carry ``ratio_vs_prefix`` (IRT ms / prefix ms,
        same run) and ``agree`` (whether both masks were identical).
    """
    rng = np.random.default_rng(seed)
    a = rng.uniform(-0.05, 1.05, n_queries)
    b = rng.uniform(-0.05, 1.05, n_queries)
    width = np.abs(rng.normal(0.0, 0.02, n_queries))  # mostly narrow ranges, like bricks
    vmin = np.minimum(a, b)
    vmax = np.minimum(vmin + width, np.maximum(a, b))
    records: list[dict[str, Any]] = []
    for n in sizes:
        tf = _bench_tf(int(n))
        alpha = tf.table[:, 3]
        ms, runs, _ = median_ms(lambda: RangeMaxTree(alpha), repeat)
        tree = opacity_range_tree(tf)
        records.append({"method": "irt", "phase": "irt_build", "table_size": int(n), "ms": ms,
                        "ms_runs": runs, "bytes": tree.nbytes, "levels": tree.levels})
        ms_irt, runs_irt, _ = median_ms(lambda: classify_irt(tree, tf, vmin, vmax), repeat)
        ms_pre, runs_pre, _ = median_ms(lambda: tf.classify(vmin, vmax), repeat)
        agree = bool(np.array_equal(classify_irt(tree, tf, vmin, vmax), tf.classify(vmin, vmax)))
        records.append({"method": "irt", "phase": "irt_query", "table_size": int(n), "ms": ms_irt,
                        "ms_runs": runs_irt, "bytes": tree.nbytes, "queries": int(n_queries),
                        "ratio_vs_prefix": ms_irt / ms_pre if ms_pre > 0 else None, "agree": agree})
        records.append({"method": "prefix", "phase": "prefix_query", "table_size": int(n), "ms": ms_pre,
                        "ms_runs": runs_pre, "bytes": int(tf._prefix.nbytes), "queries": int(n_queries)})
    return records
