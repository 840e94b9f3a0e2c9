"""Which paths a reader may open: regular files only, and text read up to a bound.

A FIFO blocks a reader forever and a symlink to ``/dev/zero`` or ``/dev/urandom``
reads until memory runs out, so every reader (volumes, meshes, particles, TF JSON,
the bench journal) opens a path only after :func:`require_regular_file`, and reads
headers and JSON through :func:`read_bounded`.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from ..errors import FileFormatError

__all__ = ["require_regular_file", "read_bounded", "file_size"]


def require_regular_file(path: str | os.PathLike, what: str = "file") -> Path:
    """``path`` as a Path if it names a regular file (symlinks followed).

    Parameters
    ----------
    path : str or PathLike
    what : str
        What the file should be, for the message (``"volume file"``).

    Raises
    ------
    FileFormatError
        The path does not exist, or is a directory, FIFO, socket or device.
    """
    p = Path(path)
    try:
        st = os.stat(p)  # follows symlinks: a link to /dev/zero is a character device
    except FileNotFoundError:
        raise FileFormatError(f"{str(p)!r}: file not found") from None
    except OSError as exc:
        raise FileFormatError(f"{str(p)!r}: cannot open {what}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        raise FileFormatError(
            f"{str(p)!r}: is a {_kind(st.st_mode)}, not a regular file; expected a regular {what}"
        )
    return p


def file_size(path: Path) -> int:
    """Size in bytes of a regular file (as :func:`require_regular_file` found it)."""
    return os.stat(path).st_size


def read_bounded(path: Path, limit: int, what: str) -> bytes:
    """The whole content of a regular file of at most ``limit`` bytes.

    Raises
    ------
    FileFormatError
        The file is not regular, or holds more than ``limit`` bytes.
    """
    require_regular_file(path, what)
    with open(path, "rb") as fh:
        data = fh.read(limit + 1)  # a file that grew after the stat is still bounded
    if len(data) > limit:
        raise FileFormatError(
            f"{str(path)!r}: {what} is larger than {limit} bytes; expected a small text file"
        )
    return data


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "directory"), (stat.S_ISFIFO, "FIFO (named pipe)"),
                       (stat.S_ISSOCK, "socket"), (stat.S_ISCHR, "character device"),
                       (stat.S_ISBLK, "block device")):
        if test(mode):
            return name
    return "special file"
