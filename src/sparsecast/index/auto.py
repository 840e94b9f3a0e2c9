"""``index="auto"``: pick a spatial index from the volume's occupancy under the TF.

The rule is deliberately small (the README's Performance section has the benchmark
volumes; a 96³ volume of random 24³ blocks at 192² gave kdtree-deep 1.8x / 1.5x
naive's speed at 52 % / 75 % of bricks non-empty, and 8 % slower than naive at 91 %):

- nothing empty to skip (at least :data:`DENSE_OCCUPANCY` of the bricks non-empty):
  ``naive``; every exact index then takes naive's samples and is slightly slower;
- the TF is being edited (a TF point dragged in the viewer: one build per frame):
  :data:`EDITING_INDEX`, the index that rebuilds in about a tenth of a millisecond;
- otherwise the index with the fastest frames on sparse data, :data:`SPARSE_INDEX`.

Occupancy is the fraction of 8³ bricks that are non-empty for the TF
(:meth:`Volume.brick_stats` and :meth:`TransferFunction.classify`): the brick
statistics are computed once per volume, the classification costs microseconds.
"""

from __future__ import annotations

from typing import Any

from .._util.checks import as_float
#: the name that lets build_index / render choose
AUTO = "auto"

__all__ = ["AUTO", "choose_index", "DENSE_OCCUPANCY", "EDITING_INDEX", "SPARSE_INDEX"]

#: non-empty brick fraction from which skipping cannot pay for its traversal
DENSE_OCCUPANCY = 0.9
#: rebuilt on every TF change (one byte per cell; 0.07-0.15 ms on the benchmark volumes)
EDITING_INDEX = "grid-pc"
#: fewest samples and fastest frames on sparse data (tens of ms to rebuild)
SPARSE_INDEX = "kdtree-deep"
#: brick edge of the occupancy estimate (the base brick size of Volume.brick_stats)
BRICK = 8


def choose_index(volume, tf, *, editing: bool = False, dense_occupancy: float = DENSE_OCCUPANCY,
                 names: list[str] | None = None) -> tuple[str, dict[str, Any]]:
    """The index ``index="auto"`` renders ``volume`` with, and why.

    Parameters
    ----------
    volume : Volume
    tf : TransferFunction
    editing : bool
        True while the TF is being edited (each frame builds a new index): prefer
        the index that rebuilds fastest.
    dense_occupancy : float
        Non-empty brick fraction from which ``naive`` is chosen.
    names : list of str, optional
        The registered indices to choose from (``build_index`` passes them; default:
        naive and the two indices named above).

    Returns
    -------
    (str, dict)
        The index name, and ``{"occupancy", "editing", "reason"}`` for
        ``Image.stats["auto"]``.
    """
    dense_occupancy = as_float(dense_occupancy, "dense_occupancy", lo=0.0, hi=1.0)
    occupancy = float(tf.classify_bricks(volume, BRICK).mean())
    if names is None:  # the registry (which imports this module) passes its names; others get the default pair
        names = ["naive", EDITING_INDEX, SPARSE_INDEX]
    if occupancy >= dense_occupancy:
        name, reason = "naive", f"{100 * occupancy:.1f} % of bricks non-empty: nothing to skip"
    elif editing and EDITING_INDEX in names:
        name, reason = EDITING_INDEX, "TF being edited: fastest rebuild"
    elif SPARSE_INDEX in names:
        name, reason = SPARSE_INDEX, f"{100 * occupancy:.1f} % of bricks non-empty: fastest frames"
    else:  # a trimmed registry: any skipping index beats naive on sparse data
        name = next((n for n in names if n != "naive"), "naive")
        reason = f"{100 * occupancy:.1f} % of bricks non-empty"
    return name, {"occupancy": round(occupancy, 4), "editing": bool(editing), "reason": reason}
