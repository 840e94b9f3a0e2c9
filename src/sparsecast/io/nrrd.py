"""NRRD volumes (``.nrrd``, ``.nhdr`` detached headers), through pynrrd."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FileFormatError
from ..volume import Volume
from .reading import Read, read_guard

__all__ = ["read_nrrd", "write_nrrd"]


def read_nrrd(path: Path) -> Read:
    """A 3-D scalar NRRD (attached or detached header; raw, gzip or bzip2 encoding).

    Spacing comes from the norms of ``space directions``, else ``spacings``; origin
    from ``space origin``. Non-scalar or non-3-D files raise FileFormatError.
    """
    import nrrd

    def _read():
        with open(path, "rb") as fh:
            header = nrrd.read_header(fh)
            dim = int(header.get("dimension", len(header.get("sizes", []))))
            sizes = [int(s) for s in header.get("sizes", [])]
            if dim != 3:
                raise FileFormatError(
                    f"{str(path)!r}: {dim}-D NRRD with sizes {sizes}; expected a 3-D scalar volume"
                )
            kinds = header.get("kinds")
            if kinds is not None:
                bad = [k for k in kinds if str(k).lower() not in ("domain", "space", "time", "none", "???")]
                if bad:
                    raise FileFormatError(
                        f"{str(path)!r}: non-scalar NRRD (axis kinds {list(kinds)}); "
                        f"expected a 3-D scalar volume with kinds 'domain' or 'space'"
                    )
            data = nrrd.read_data(header, fh, str(path), index_order="C")
        return data, header

    data, header = read_guard(path, "NRRD", _read)

    spacing = None
    dirs = header.get("space directions")
    if dirs is not None:
        dirs = np.asarray(dirs, dtype=np.float64)
        if dirs.ndim == 2 and dirs.shape[0] == 3:
            norms = np.linalg.norm(dirs, axis=1)
            if np.all(np.isfinite(norms)) and np.all(norms > 0):
                spacing = norms
    if spacing is None and header.get("spacings") is not None:
        sp = np.asarray(header["spacings"], dtype=np.float64)
        if sp.shape == (3,) and np.all(np.isfinite(sp)) and np.all(sp > 0):
            spacing = sp
    origin = None
    org = header.get("space origin")
    if org is not None:
        org = np.asarray(org, dtype=np.float64).ravel()
        if org.shape == (3,) and np.all(np.isfinite(org)):
            origin = org
    return data, spacing, origin


def write_nrrd(volume: Volume, tmp: Path, compress: bool) -> None:
    """Axes x y z, ``space directions`` = diag(spacing), ``space origin``; gzip when ``compress``."""
    import nrrd

    header = {
        "space dimension": 3,
        "space directions": np.diag(volume.spacing.astype(np.float64)),
        "space origin": volume.origin.astype(np.float64),
        "kinds": ["domain", "domain", "domain"],
        "encoding": "gzip" if compress else "raw",
    }
    # index_order='C': array (nz, ny, nx) -> sizes "nx ny nz", x fastest, as NRRD expects.
    nrrd.write(str(tmp), np.ascontiguousarray(volume.data), header, index_order="C", compression_level=6)
