"""How much memory a file may make a reader allocate: the declared-size checks.

A header states a shape; a small file can state any shape (a 13.8 kB NIfTI claiming
12 GB, a ``.npy`` claiming 909 TiB). Before a reader allocates what a header
claims it calls :func:`check_declared`, which refuses

* a payload stored uncompressed that the file is too small to hold
  (``available`` bytes from the payload's start), and
* any declared size above :func:`memory_limit`, compressed or not, so that a
  compression bomb is refused before it is inflated.

The limit is half the physical memory (``os.sysconf``), or the number of bytes in
the environment variable ``SPARSECAST_MAX_VOLUME_BYTES`` when set (tests, shared
machines).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import FileFormatError

__all__ = ["memory_limit", "check_declared", "LIMIT_ENV", "GZIP_MAX_RATIO"]

#: environment variable overriding :func:`memory_limit` (bytes)
LIMIT_ENV = "SPARSECAST_MAX_VOLUME_BYTES"
#: deflate cannot expand input by more than about 1032:1, so a gzip stream of
#: ``n`` bytes never holds more than ``GZIP_MAX_RATIO * n`` (header slack included)
GZIP_MAX_RATIO = 1100
_FALLBACK = 4 << 30  # where sysconf cannot tell (not POSIX)


def memory_limit() -> int:
    """The most bytes one volume's payload may declare.

    Half the physical memory (a loaded volume is converted at least once, so twice
    its size must fit), or ``$SPARSECAST_MAX_VOLUME_BYTES``.
    """
    env = os.environ.get(LIMIT_ENV, "").strip()
    if env.isascii() and env.isdigit():
        return int(env)
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2
    except (AttributeError, ValueError, OSError):
        return _FALLBACK


def _gib(n: int) -> str:
    return f"{n} bytes ({n / 2**30:.3g} GiB)"


def check_declared(path: Path, declared: int, what: str, *, available: int | None = None,
                   compressed_bytes: int | None = None) -> None:
    """Refuse a payload of ``declared`` bytes that the file cannot hold or memory cannot take.

    Parameters
    ----------
    path : Path
        The file, for the message.
    declared : int
        Bytes the header says the payload decodes to (shape x item size).
    what : str
        Where the claim comes from (``"NIfTI header (shape (512, 512, 300), int16)"``).
    available : int, optional
        Bytes the file holds from the payload's start, for payloads stored as they
        are (raw): the file must hold at least ``declared``.
    compressed_bytes : int, optional
        Size of a gzip payload: it cannot decode to more than
        :data:`GZIP_MAX_RATIO` times that.

    Raises
    ------
    FileFormatError
        One line naming the file, the declared size and the bound it exceeds.
    """
    if available is not None and declared > available:
        raise FileFormatError(
            f"{str(path)!r}: {what} declares {declared} bytes of data, but the file holds only "
            f"{max(available, 0)} bytes after the header (file truncated, or the header is wrong)"
        )
    if compressed_bytes is not None and declared > GZIP_MAX_RATIO * max(compressed_bytes, 1) + 4096:
        raise FileFormatError(
            f"{str(path)!r}: {what} declares {declared} bytes of data, more than {compressed_bytes} "
            f"bytes of gzip can hold (at most about {GZIP_MAX_RATIO}:1); the header is wrong"
        )
    limit = memory_limit()
    if declared > limit:
        raise FileFormatError(
            f"{str(path)!r}: {what} declares {_gib(declared)} of data, above the limit of "
            f"{_gib(limit)} (half the physical memory; set ${LIMIT_ENV} to change it)"
        )
