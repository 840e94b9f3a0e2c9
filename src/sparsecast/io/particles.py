"""Particle readers: PLY (via trimesh), CSV and ``.npy`` -> :class:`~sparsecast.elements.ParticleSet`.

Columns (CSV and ``.npy``): ``x y z`` then optionally ``radius`` and ``r g b``
(3, 4 or 7 columns). A CSV may have a header naming the columns ``x, y, z``
(required), ``radius`` and ``red, green, blue``; every other named column (a
catalogue's ``mag``, a simulation's ``mass``) becomes a per-particle attribute to
colour by. Colours above 1 are read as 0..255. PLY vertices give the centres, a
``radius`` (or ``scale``) vertex property the radii, vertex colours the colours and
other scalar vertex properties the attributes. Without radii in the file every
particle gets ``radius``, by default
:func:`~sparsecast.elements.default_particle_radius` (the median distance to the
8th nearest neighbour).
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from .._util.checks import positive_float
from ..elements import ParticleSet
from ..errors import FileFormatError
from .files import require_regular_file
from .npy import read_npy_array
from .reading import read_guard

__all__ = ["load_particles", "PARTICLE_SUFFIXES"]

PARTICLE_SUFFIXES = (".ply", ".csv", ".npy")
_RGB = ("red", "green", "blue")
#: columns / vertex properties with a meaning of their own (not attributes)
_KNOWN_COLUMNS = {"x", "y", "z", "radius", "scale", "red", "green", "blue", "alpha", "nx", "ny", "nz"}


def load_particles(path: str | os.PathLike, *, radius: float | None = None) -> ParticleSet:
    """Read spheres from a PLY, CSV or ``.npy`` file (see the module docstring).

    Parameters
    ----------
    path : path-like
    radius : float, optional
        Radius of every particle when the file has none (and only then); default
        from the data (:func:`~sparsecast.elements.default_particle_radius`; the
        set's ``radius_estimated`` is then True).

    Raises
    ------
    FileFormatError
        Missing or not a regular file, unknown suffix, or content that is not a
        particle table (a header-only CSV, a PLY without ``end_header``, a
        structured or empty ``.npy``, NaN/Inf centres, radii or colours).
    ParameterError
        ``radius`` is not a positive number.
    """
    if radius is not None:
        radius = positive_float(radius, "radius")
    p = Path(path)
    require_regular_file(p, "particle file")
    suffix = p.suffix.lower()
    if suffix not in PARTICLE_SUFFIXES:
        raise FileFormatError(f"{str(p)!r}: unknown particle file suffix {suffix!r}; expected one of {PARTICLE_SUFFIXES}")
    attributes: dict[str, np.ndarray] = {}
    if suffix == ".ply":
        centers, radii, colors, attributes = read_guard(p, "PLY particles", _read_ply, p)
    elif suffix == ".csv":
        table, header = read_guard(p, "CSV particles", _read_csv, p)
        if header is None:
            centers, radii, colors = _columns(table, p)
        else:
            centers, radii, colors, attributes = _named_columns(table, header, p)
    else:
        centers, radii, colors = _columns(read_npy_array(p, "NumPy .npy particles"), p)
    if radii is None and radius is not None:
        radii = np.full(centers.shape[0], float(radius))
    if not np.all(np.isfinite(centers)):
        bad = int(np.argmax(~np.isfinite(centers).all(axis=1)))
        raise FileFormatError(f"{str(p)!r}: particle {bad} has a NaN or infinite centre; expected finite x, y, z")
    if colors is not None:
        if not np.all(np.isfinite(colors)):
            bad = int(np.argmax(~np.isfinite(colors).all(axis=1)))
            raise FileFormatError(f"{str(p)!r}: particle {bad} has a NaN or infinite colour; expected "
                                  f"numbers in [0, 1] (or 0..255)")
        if colors.size and colors.max() > 1.0:
            colors = colors / 255.0
    try:
        return ParticleSet(centers, radii, colors, name=p.name, attributes=attributes)
    except ValueError as exc:
        raise FileFormatError(f"{str(p)!r}: {exc}") from None


def _columns(a: np.ndarray, p: Path):
    if a.dtype.names is not None or a.dtype.kind not in "biuf":
        raise FileFormatError(
            f"{str(p)!r}: array of dtype {a.dtype}; expected a plain numeric table (not structured)"
        )
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 1 and a.size in (3, 4, 7):
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] not in (3, 4, 7):
        raise FileFormatError(
            f"{str(p)!r}: expected a table of 3 (x y z), 4 (+ radius) or 7 (+ r g b) columns, got shape {a.shape}"
        )
    radii = a[:, 3] if a.shape[1] >= 4 else None
    colors = a[:, 4:7] if a.shape[1] == 7 else None
    return a[:, :3], radii, colors


def _read_csv(p: Path) -> np.ndarray:
    with open(p, encoding="utf-8") as f:
        first = f.readline()
    cells = [c.strip().lower() for c in first.split(",")]
    try:
        [float(c) for c in cells]
        header = None
    except ValueError:
        header = cells
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "input contained no data": reported below
        a = np.loadtxt(p, delimiter=",", skiprows=1 if header else 0, ndmin=2)
    if a.size == 0:
        raise FileFormatError(f"{str(p)!r}: CSV holds no particle rows" + (" (only a header)" if header else ""))
    return a, header


def _named_columns(a: np.ndarray, header: list[str], p: Path):
    """Centres, radii, colours and attributes of a CSV table with a header row."""
    if len(header) != a.shape[1]:
        raise FileFormatError(f"{str(p)!r}: header names {len(header)} columns, rows hold {a.shape[1]}")
    missing = [c for c in ("x", "y", "z") if c not in header]
    if missing:
        raise FileFormatError(f"{str(p)!r}: header {header} lacks column(s) {missing}")
    col = {name: a[:, header.index(name)] for name in header}
    radii = col.get("radius")
    colors = np.stack([col[c] for c in _RGB], 1) if all(c in col for c in _RGB) else None
    attributes = {name: v for name, v in col.items() if name not in _KNOWN_COLUMNS}
    return np.stack([col["x"], col["y"], col["z"]], 1), radii, colors, attributes


def _read_ply(p: Path):
    import trimesh

    geom = trimesh.load(p, process=False)
    centers = np.asarray(geom.vertices, dtype=np.float64)
    radii = None
    raw = getattr(geom, "metadata", {}).get("_ply_raw", {})
    vdata = raw.get("vertex", {}).get("data") if isinstance(raw, dict) else None
    # binary PLY: a structured array; ASCII PLY: a dict of columns
    names = vdata.keys() if isinstance(vdata, dict) else (getattr(getattr(vdata, "dtype", None), "names", None) or ())
    for name in ("radius", "scale"):
        if name in names:
            radii = np.asarray(vdata[name], dtype=np.float64).reshape(-1)
            break
    attributes = {}
    for name in names:
        v = np.asarray(vdata[name])
        # scalar numeric properties only (a list property is not a per-particle value)
        if name not in _KNOWN_COLUMNS and v.dtype.kind in "biuf" and v.size == len(centers):
            attributes[name] = v.astype(np.float64).reshape(-1)
    colors = None
    vc = getattr(geom, "colors", None)
    if vc is None and hasattr(geom, "visual") and getattr(geom.visual, "kind", None) == "vertex":
        vc = geom.visual.vertex_colors
    if vc is not None and len(vc) == len(centers):
        colors = np.asarray(vc, dtype=np.float64)[:, :3] / 255.0
    return centers, radii, colors, attributes
