"""Atomic file output: write to a temporary name beside the target, then rename."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ..errors import ParameterError

__all__ = ["atomic_path"]


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    If the body raises, the temporary file is removed and ``path`` is untouched, so
    a failed or interrupted write never leaves a partial output behind.

    The temporary name keeps the target's suffix(es) so that writers which pick a
    format from the file name (Pillow, nibabel, pynrrd) still do the right thing.

    Examples
    --------
    >>> with atomic_path("out.png") as tmp:      # doctest: +SKIP
    ...     image.save(tmp)
    """
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise ParameterError(f"output {str(target)!r}: directory {str(parent)!r} does not exist")
    suffix = "".join(target.suffixes) or ""
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=".part" + suffix, dir=parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        # mkstemp creates the file 0600; give the output the mode a plain open()
        # would (or the mode of the file it replaces), so reports stay readable.
        with contextlib.suppress(FileNotFoundError):
            os.chmod(tmp, _output_mode(target))
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _output_mode(target: Path) -> int:
    try:
        return target.stat().st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask
