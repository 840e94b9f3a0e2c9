"""What every volume reader shares: the value it returns (:data:`Read`) and one error for
every unreadable file (:func:`read_guard`).

pynrrd, nibabel, tifffile and NumPy each raise their own exceptions for a corrupt,
truncated or mislabelled file; the command line prints a :class:`SparsecastError`
as one line, so every reader calls its library through :func:`read_guard`.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple, Optional

import numpy as np

from ..errors import FileFormatError, SparsecastError

__all__ = ["Read", "read_guard", "read_error"]

class Read(NamedTuple):
    """What a reader returns: the array ``(nz, ny, nx)``, and the spacing and origin the
    file stores (``(x, y, z)``) and its anatomical axis codes (``("L", "P", "S")``, see
    :mod:`sparsecast.axes`), each None where it stores none. Readers of formats without
    orientation may return a plain 3-tuple (``Read(*result)`` fills in None)."""

    data: np.ndarray
    spacing: Optional[np.ndarray]
    origin: Optional[np.ndarray]
    orientation: Optional[tuple[str, str, str]] = None


def read_error(path: Path, exc: BaseException, what: str = "") -> FileFormatError:
    """The FileFormatError for ``exc`` raised while reading ``path`` (as ``what``)."""
    detail = str(exc) or type(exc).__name__
    kind = f" as {what}" if what else ""
    return FileFormatError(
        f"{str(path)!r}: cannot read{kind}: {type(exc).__name__}: {detail} "
        f"(file corrupt, truncated or not in the format its name says)"
    )


def read_guard(path: Path, what: str, fn, *args, **kwargs):
    """Call a library reader; turn any library exception into FileFormatError."""
    try:
        return fn(*args, **kwargs)
    except (SparsecastError, MemoryError, KeyboardInterrupt):
        raise
    except Exception as exc:  # noqa: BLE001 - boundary: every library error is reported alike
        raise read_error(path, exc, what) from exc
