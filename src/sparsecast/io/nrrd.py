"""NRRD volumes (``.nrrd``, ``.nhdr`` detached headers): pynrrd parses the header, this
module fetches the payload within bounds.

pynrrd's ``read_data`` reads a whole compressed payload and inflates all of it
before it compares sizes (a 2.2 kB bzip2 file expands to 3 GB), follows a
``data file:`` to any absolute path, and skips ``line skip`` lines one ``readline``
at a time. So the header comes from ``nrrd.read_header`` (read from at most
:data:`HEADER_LIMIT` bytes) and the payload from :func:`_payload`, which

* checks the declared size against the file (raw) and the memory limit
  (:func:`~.budget.check_declared`) before allocating,
* inflates gzip/bzip2 in a stream that stops at the declared size and fails if
  the stream holds more or less,
* bounds ``line skip`` and ``byte skip`` by the file size, and
* resolves ``data file:`` relative to the header and refuses a file outside the
  header's folder unless ``allow_outside=True``.
"""

from __future__ import annotations

import bz2
import math
import os
import zlib
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..axes import axcodes, space_directions
from ..errors import FileFormatError
from ..volume import Volume
from .budget import check_declared, memory_limit
from .files import file_size, require_regular_file
from .reading import Read, read_guard

__all__ = ["read_nrrd", "raw_payload", "RawPayload", "EncodedPayloadError", "write_nrrd", "HEADER_LIMIT", "SPACES"]

#: NRRD ``space`` values with an anatomical meaning -> the directions of its +x, +y, +z
#: (the spec's long names and abbreviations; other spaces, e.g. scanner-xyz, have none)
SPACES: dict[str, tuple[str, str, str]] = {
    "right-anterior-superior": ("R", "A", "S"), "ras": ("R", "A", "S"),
    "left-anterior-superior": ("L", "A", "S"), "las": ("L", "A", "S"),
    "left-posterior-superior": ("L", "P", "S"), "lps": ("L", "P", "S"),
}

#: bytes an NRRD header may take (real ones are a few hundred)
HEADER_LIMIT = 1 << 20
_CHUNK = 1 << 20
_ENCODINGS = {"raw": "raw", "gzip": "gzip", "gz": "gzip", "bzip2": "bzip2", "bz2": "bzip2",
              "ascii": "ascii", "text": "ascii", "txt": "ascii"}


def read_nrrd(path: Path, *, allow_outside: bool = False) -> Read:
    """A 3-D scalar NRRD (attached or detached header; raw, gzip, bzip2 or ASCII encoding).

    Spacing comes from the norms of ``space directions``, else ``spacings``; origin
    from ``space origin``; the anatomical orientation (axis codes) from ``space``
    (:data:`SPACES`) and the signs and order of ``space directions``.

    Parameters
    ----------
    path : Path
        The ``.nrrd`` or ``.nhdr`` file.
    allow_outside : bool
        Follow a ``data file:`` that resolves outside the header's folder (an
        absolute path, ``..``, a symlink out). Off by default: a header from
        elsewhere must not read arbitrary files as voxels.

    Raises
    ------
    FileFormatError
        Not a 3-D scalar NRRD, a header or payload that is too large, truncated or
        longer than declared, or a data file outside the header's folder.
    """
    header, header_size, sizes = _scalar_header(path)
    data = _payload(path, header, header_size, sizes, allow_outside)
    return Read(data, _spacing(header), _origin(header), _orientation(header))


class EncodedPayloadError(FileFormatError):
    """A compressed or ASCII NRRD payload asked for as a raw one (:func:`raw_payload`): it
    cannot be mapped, only decoded whole (:func:`read_nrrd`)."""


class RawPayload(NamedTuple):
    """Where a raw-encoded NRRD's voxels lie (see :func:`raw_payload`)."""

    file: Path
    offset: int
    dtype: np.dtype
    shape: tuple[int, int, int]
    spacing: np.ndarray | None
    origin: np.ndarray | None
    orientation: tuple[str, str, str] | None


def raw_payload(path: Path, *, allow_outside: bool = False) -> RawPayload:
    """The file, byte offset, dtype and shape ``(nz, ny, nx)`` of a raw-encoded NRRD's
    payload, with its spacing, origin and orientation; nothing of the payload is read
    (a memory map takes it from here, at any size).

    Raises
    ------
    FileFormatError
        As :func:`read_nrrd`, and for a compressed or ASCII payload, which cannot be
        mapped: it must be decoded whole.
    """
    header, header_size, sizes = _scalar_header(path)
    encoding = _ENCODINGS.get(str(header.get("encoding", "")).lower())
    if encoding != "raw":
        raise EncodedPayloadError(
            f"{str(path)!r}: {header.get('encoding')}-encoded NRRD payload cannot be read lazily (it must "
            f"be decoded whole); expected encoding raw; load it into memory, or convert it once "
            f"(sparsecast convert {path.name} OUT.zarr) and open the Zarr store"
        )
    source, offset = _payload(path, header, header_size, sizes, allow_outside, locate=True)
    return RawPayload(source, offset, _dtype(path, header), tuple(sizes[::-1]), _spacing(header),
                      _origin(header), _orientation(header))


def _scalar_header(path: Path) -> tuple[dict, int, list[int]]:
    """The header of a 3-D scalar NRRD, its length in bytes and its sizes (x fastest)."""
    require_regular_file(path, "NRRD file")
    header, header_size = _read_header(path)
    dim = int(header.get("dimension", len(header.get("sizes", []))))
    sizes = [int(s) for s in header.get("sizes", [])]
    if dim != 3 or len(sizes) != 3 or min(sizes) <= 0:
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
    return header, header_size, sizes


def _read_header(path: Path) -> tuple[dict, int]:
    """The parsed header and its length in bytes (through the blank line that ends it)."""
    import nrrd

    size = file_size(path)
    with open(path, "rb") as fh:
        head = fh.read(HEADER_LIMIT)
    lines, length, ended = [], 0, False
    for line in head.splitlines(keepends=True):
        if not line.endswith(b"\n") and length + len(line) == HEADER_LIMIT:
            break  # cut by the bound, not by the file
        lines.append(line)
        length += len(line)
        if len(lines) > 1 and not line.startswith(b"#") and line.strip() == b"":
            ended = True
            break
    # A detached header may end at the end of its file, without a blank line.
    if not ended and size > HEADER_LIMIT:
        raise FileFormatError(
            f"{str(path)!r}: no end of the NRRD header (a blank line) in the first "
            f"{HEADER_LIMIT} bytes; expected a header of at most that size"
        )
    if not lines:
        raise FileFormatError(f"{str(path)!r}: empty file; expected an NRRD header")
    header = read_guard(path, "NRRD", nrrd.read_header, lines)
    return header, length


def _dtype(path: Path, header: dict) -> np.dtype:
    # pynrrd's mapping of NRRD type names (and endian) to NumPy; it is not public API,
    # but it is the one table pynrrd's own read_data uses.
    from nrrd.reader import _determine_datatype

    return read_guard(path, "NRRD", _determine_datatype, header)


def _field(header: dict, name: str, default):
    """A field spelled with or without its space (``byte skip`` / ``byteskip``)."""
    return header.get(name, header.get(name.replace(" ", ""), default))


def _data_path(path: Path, name: str, allow_outside: bool) -> Path:
    folder = Path(os.path.abspath(path)).parent.resolve()
    if not name or "\x00" in name or len(name) > 4096:
        raise FileFormatError(f"{str(path)!r}: data file {name[:100]!r} is not a usable file name")
    try:
        target = (folder / name).resolve()
    except (OSError, RuntimeError) as exc:  # a symlink loop, a name too long
        raise FileFormatError(f"{str(path)!r}: data file {name[:100]!r}: {exc}") from None
    if not allow_outside and not target.is_relative_to(folder):
        raise FileFormatError(
            f"{str(path)!r}: data file {name!r} resolves to {str(target)!r}, outside the header's "
            f"folder {str(folder)!r}; expected a file beside the header (pass allow_outside=True, "
            f"or --allow-outside-data, to read it anyway)"
        )
    try:
        return require_regular_file(target, "NRRD data file")
    except FileFormatError as exc:
        raise FileFormatError(f"{str(path)!r}: data file {name!r}: {exc}") from None


def _payload(path: Path, header: dict, header_size: int, sizes: list[int], allow_outside: bool,
             locate: bool = False):
    """The payload as an array (nz, ny, nx); with ``locate`` (raw encoding only), the
    ``(data file, byte offset)`` where it starts instead, its size checked."""
    dtype = _dtype(path, header)
    count = math.prod(sizes)
    declared = count * dtype.itemsize
    what = f"NRRD header (sizes {' '.join(map(str, sizes))}, {dtype.name})"
    encoding = _ENCODINGS.get(str(header.get("encoding", "")).lower())
    if encoding is None:
        raise FileFormatError(
            f"{str(path)!r}: unsupported NRRD encoding {header.get('encoding')!r}; "
            f"expected raw, gzip, bzip2 or ascii"
        )
    line_skip = int(_field(header, "line skip", 0))
    byte_skip = int(_field(header, "byte skip", 0))
    data_name = _field(header, "data file", None)
    if data_name is not None:
        source, start = _data_path(path, str(data_name), allow_outside), 0
    else:
        source, start = path, header_size
    total = file_size(source)
    if line_skip < 0 or line_skip > total - start:
        raise FileFormatError(
            f"{str(path)!r}: line skip {line_skip} is not in [0, {total - start}] (the bytes after "
            f"the header); expected a count of lines the data file holds"
        )
    if byte_skip < -1:
        raise FileFormatError(f"{str(path)!r}: byte skip {byte_skip}; expected -1 or more")
    with open(source, "rb") as fh:
        fh.seek(start)
        _skip_lines(fh, line_skip, path)
        pos = fh.tell()
        if encoding in ("gzip", "bzip2"):
            skip = max(byte_skip, 0)  # applied after inflating; -1 means "the data is at the end"
            check_declared(path, declared + skip, what,
                           compressed_bytes=(total - pos) if encoding == "gzip" else None)
            buf = _inflate(fh, encoding, declared + skip, path, byte_skip == -1)
            return _shaped(np.frombuffer(buf, dtype, count=count, offset=len(buf) - declared), sizes)
        if byte_skip > total - pos:
            raise FileFormatError(
                f"{str(path)!r}: byte skip {byte_skip} is beyond the end of the data file "
                f"({total - pos} bytes after the header and skipped lines)"
            )
        if encoding == "ascii":
            fh.seek(max(byte_skip, 0), os.SEEK_CUR)
            # every value takes at least one digit and one separator (the last none)
            check_declared(path, 2 * count - 1, f"NRRD header (sizes {' '.join(map(str, sizes))}, ascii)",
                           available=total - fh.tell())
            check_declared(path, declared, what)
            text = fh.read()
            arr = read_guard(path, "NRRD", np.fromstring, text, dtype, sep=" ")
            if arr.size != count:
                raise FileFormatError(
                    f"{str(path)!r}: ASCII payload holds {arr.size} values, the header declares {count}"
                )
            return _shaped(arr, sizes)
        if byte_skip == -1:
            pos = total - declared  # the data is the last bytes of the file
        else:
            pos += byte_skip
        if locate:
            if pos < fh.tell() or declared > total - pos:
                raise FileFormatError(
                    f"{str(path)!r}: {what} declares {declared} bytes of data, but the file holds only "
                    f"{max(total - pos, 0) if pos >= fh.tell() else 0} bytes after the header (file truncated, "
                    f"or the header is wrong)"
                )
        else:
            check_declared(path, declared, what, available=total - pos if pos >= fh.tell() else -1)
        if total - pos > declared:
            raise FileFormatError(
                f"{str(path)!r}: the raw payload holds {total - pos} bytes, the header declares "
                f"{declared}; expected exactly that many"
            )
        if locate:
            return source, pos
        fh.seek(pos)
        arr = read_guard(path, "NRRD", np.fromfile, fh, dtype, count)
    if arr.size != count:
        raise FileFormatError(f"{str(path)!r}: read {arr.size} values, the header declares {count}")
    return _shaped(arr, sizes)


def _shaped(arr: np.ndarray, sizes: list[int]) -> np.ndarray:
    return arr.reshape(tuple(sizes[::-1]))  # NRRD sizes are x fastest: (nz, ny, nx)


def _skip_lines(fh, n: int, path: Path) -> None:
    """Move ``fh`` past ``n`` newlines, scanning in chunks (a line may be any length)."""
    while n > 0:
        chunk = fh.read(_CHUNK)
        if not chunk:
            raise FileFormatError(f"{str(path)!r}: line skip runs past the end of the data file")
        found = chunk.count(b"\n")
        if found < n:
            n -= found
            continue
        cut = -1
        for _ in range(n):
            cut = chunk.index(b"\n", cut + 1)
        fh.seek(cut + 1 - len(chunk), os.SEEK_CUR)
        return


def _inflate(fh, encoding: str, need: int, path: Path, keep_tail: bool) -> bytearray:
    """Exactly ``need`` bytes inflated from ``fh``, never more than ``need + 1`` in memory.

    With ``keep_tail`` (``byte skip: -1``: the data is the end of the stream) the
    last ``need`` bytes are kept; the stream may then be longer, but not longer than
    the memory limit (so a bomb still ends).
    """
    if encoding == "gzip":
        z = zlib.decompressobj(zlib.MAX_WBITS | 16)

        def step(room: int) -> bytes | None:
            data = z.unconsumed_tail or fh.read(_CHUNK)
            return z.decompress(data, room) if data else None

        def finished() -> bool:
            return z.eof
    else:
        b = bz2.BZ2Decompressor()

        def step(room: int) -> bytes | None:
            data = fh.read(_CHUNK) if b.needs_input else b""
            if not data and b.needs_input:
                return None
            return b.decompress(data, room)

        def finished() -> bool:
            return b.eof

    out = bytearray()
    total, limit = 0, memory_limit()
    while not finished():
        piece = read_guard(path, "NRRD", step, _CHUNK if keep_tail else need + 1 - len(out))
        if piece is None:
            break  # the input ended before the stream did: truncated
        out += piece
        total += len(piece)
        if keep_tail:
            if len(out) > need:
                del out[: len(out) - need]
            if total > limit:
                raise FileFormatError(
                    f"{str(path)!r}: the {encoding} payload inflates to more than {limit} bytes "
                    f"(the memory limit); expected {need}"
                )
        elif len(out) > need:
            raise FileFormatError(
                f"{str(path)!r}: the {encoding} payload holds more than the {need} bytes the header "
                f"declares; expected exactly that many"
            )
    if len(out) < need:
        raise FileFormatError(
            f"{str(path)!r}: the {encoding} payload holds {len(out)} bytes, the header declares "
            f"{need} (file truncated, or the header is wrong)"
        )
    return out


def _spacing(header: dict) -> np.ndarray | None:
    dirs = header.get("space directions")
    if dirs is not None:
        dirs = np.asarray(dirs, dtype=np.float64)
        if dirs.ndim == 2 and dirs.shape[0] == 3:
            norms = np.linalg.norm(dirs, axis=1)
            if np.all(np.isfinite(norms)) and np.all(norms > 0):
                return norms
    if header.get("spacings") is not None:
        sp = np.asarray(header["spacings"], dtype=np.float64)
        if sp.shape == (3,) and np.all(np.isfinite(sp)) and np.all(sp > 0):
            return sp
    return None


def _orientation(header: dict) -> tuple[str, str, str] | None:
    """Axis codes of +i, +j, +k: the ``space``'s axes, as ``space directions`` map the
    voxel axes onto them (a negative direction flips the code); None without an
    anatomical space."""
    space = SPACES.get(str(header.get("space", "")).strip().lower())
    if space is None:
        return None
    dirs = header.get("space directions")
    if dirs is None:  # spacings only: the voxel axes are the space's axes
        return space
    dirs = np.asarray(dirs, dtype=np.float64)
    # Rows are the voxel axes' vectors; axcodes takes them as columns.
    return axcodes(dirs.T, space) if dirs.shape == (3, 3) else None


def _origin(header: dict) -> np.ndarray | None:
    org = header.get("space origin")
    if org is not None:
        org = np.asarray(org, dtype=np.float64).ravel()
        if org.shape == (3,) and np.all(np.isfinite(org)):
            return org
    return None


def write_nrrd(volume: Volume, tmp: Path, compress: bool) -> None:
    """Axes x y z, ``space directions`` = diag(spacing), ``space origin``; gzip when ``compress``.

    A volume with an orientation gets ``space: left-posterior-superior`` (DICOM's frame),
    its axes' codes in the signs and order of ``space directions``; one without gets
    ``space dimension: 3`` (no anatomical meaning claimed).
    """
    import nrrd

    space: dict = {"space dimension": 3}
    directions = np.diag(volume.spacing.astype(np.float64))
    if volume.orientation is not None:
        space = {"space": "left-posterior-superior"}
        # Rows are the voxel axes' vectors in LPS: the codes' unit vectors, scaled.
        directions = space_directions(volume.orientation, ("L", "P", "S")).T * volume.spacing[:, None]
    header = {
        **space,
        "space directions": directions,
        "space origin": volume.origin.astype(np.float64),
        "kinds": ["domain", "domain", "domain"],
        "encoding": "gzip" if compress else "raw",
    }
    # index_order='C': array (nz, ny, nx) -> sizes "nx ny nz", x fastest, as NRRD expects.
    nrrd.write(str(tmp), np.ascontiguousarray(volume.data), header, index_order="C", compression_level=6)
