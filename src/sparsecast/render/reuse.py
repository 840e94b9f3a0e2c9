"""The index :func:`~sparsecast.render.render` builds from a name, kept with the volume for the next frame.

A script or notebook that renders a camera path with ``render(volume, tf, camera)``
(``index="auto"``) or any index name used to rebuild the index for every frame: tens
to hundreds of milliseconds on the shared CT volumes, often more than the frame
itself. An exact index depends on its TF only through what the TF leaves empty (it
skips space by emptiness and nothing else, and the frame's own TF table does the
compositing), so the index built for an earlier TF serves every later TF with the
same emptiness (:func:`same_emptiness`): moving a colour, or an opacity that stays
non-zero, reuses it; making a value range empty or non-empty rebuilds it, as do
other index options. Indices for different emptinesses are kept side by side (an
isosurface frame's classification TF and the DVR TF of the next frame each find
theirs). The indices live in the volume's :meth:`derived
<sparsecast.volume.Volume.derived>` store, so they die with the volume, at most a
few per volume. Approximate indices (the BIH's sampling modes) read more of the TF
and are built afresh each time.
"""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np

from ..index import SpatialIndex, build_index
from ..transfer import TransferFunction
from ..volume import Volume

__all__ = ["index_for_frame", "same_emptiness"]


def same_emptiness(a: TransferFunction, b: TransferFunction) -> bool:
    """Whether an index built for ``a`` skips exactly what one built for ``b`` would:
    trilinear TFs with the same range, table size and zero/non-zero opacity entries
    (emptiness is decided by the prefix count of non-zero entries, nothing else)."""
    if a is b:
        return True
    return (type(a) is type(b) is TransferFunction and a.value_range == b.value_range
            and a.table_size == b.table_size and np.array_equal(a.prefix, b.prefix))


def _emptiness_key(tf: TransferFunction) -> tuple:
    """A hashable digest of what :func:`same_emptiness` compares (equal for TFs it calls
    the same; a collision only costs a rebuild, as the kept index's TF is checked)."""
    if type(tf) is not TransferFunction:
        return (type(tf).__name__, id(tf))  # same_emptiness: only the same object
    prefix = np.ascontiguousarray(tf.prefix)
    return (tuple(map(float, tf.value_range)), int(tf.table_size),
            hashlib.blake2b(prefix.tobytes(), digest_size=16).digest())


def index_for_frame(volume: Volume, tf: TransferFunction, name: str,
                    options: dict[str, Any]) -> tuple[SpatialIndex, bool]:
    """The index ``name`` (with ``options``) for ``volume`` classified by ``tf``.

    Returns
    -------
    index : SpatialIndex
        The one kept from an earlier frame when it is exact and was built for a TF
        of the same emptiness as ``tf``, else a new one (then kept if exact).
    reused : bool
        Whether it was kept from an earlier frame (its build cost nothing now).
    """
    # Spacing and origin are plain attributes a caller may change: part of the key. So
    # is what the TF leaves empty, so that indices of two emptinesses live side by side:
    # a viewer toggling isosurface and DVR frames (two classification TFs) used to
    # rebuild the index at every toggle.
    key = ("render-index", name, tuple(sorted((k, repr(v)) for k, v in options.items())),
           tuple(map(float, volume.spacing)), tuple(map(float, volume.origin)), _emptiness_key(tf))
    kept = volume.derived(key)
    if kept is not None and same_emptiness(kept.tf, tf):
        return kept, True
    index = build_index(volume, tf, name, **options)
    if index.exact:
        volume.keep_derived(key, index)
    return index, False
