"""Atomic file output: check the target first, write to a temporary name beside it, then rename.

* :func:`check_output` validates a target before any work (suffix, folder,
  writability, name length), so a bad ``-o`` fails in milliseconds, not after a
  render, and an earlier output is never replaced before a later one is rejected.
* :func:`atomic_path` yields the temporary path. A symlink target is written
  *through*: the file it points to is replaced and the link stays. Write failures
  (disk full, read-only file system) become one
  :class:`~sparsecast.errors.FileFormatError` line, and the temporary is removed on
  every failure path.
* Temporaries are named ``.sparsecast-<pid>-<random>.part<suffix>``, short enough
  for any target name the file system allows; a killed process can leave one
  behind, so the next write to the same folder removes those whose process is gone.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Collection, Iterator
from pathlib import Path

from ..errors import FileFormatError, ParameterError

__all__ = ["atomic_path", "check_output", "TEMP_PREFIX"]

#: how every temporary output name starts
TEMP_PREFIX = ".sparsecast-"
_TEMP_RE = re.compile(re.escape(TEMP_PREFIX) + r"(?P<pid>[0-9]+)-[A-Za-z0-9_]{8}\.part", re.ASCII)


def _name_max(folder: Path) -> int:
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        return 255


def _resolve(path: str | os.PathLike) -> Path:
    """The file a write to ``path`` must replace: a symlink's target (write-through)."""
    p = Path(path)
    return Path(os.path.realpath(p)) if p.is_symlink() else p


def check_output(path: str | os.PathLike, name: str = "output",
                 suffixes: Collection[str] | None = None) -> Path:
    """Refuse an output that cannot be written, before any work is done.

    Parameters
    ----------
    path : str or PathLike
        The target file.
    name : str
        The option or parameter, for the message (``-o``, ``--array``).
    suffixes : collection of str, optional
        Accepted lower-case suffixes (``{".png", ".npy"}``).

    Returns
    -------
    Path
        The file that will be replaced (a symlink's target).

    Raises
    ------
    ParameterError
        Wrong suffix, missing or unwritable folder, a folder at the target, or a
        name longer than the file system allows.
    """
    p = Path(path)
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise ParameterError(
            f"{name}: {str(p)!r} has suffix {p.suffix or '(none)'!r}; expected one of {', '.join(sorted(suffixes))}"
        )
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise ParameterError(f"{name}: {str(p)!r}: directory {str(folder)!r} does not exist")
    limit = _name_max(folder)
    if len(os.fsencode(p.name)) > limit:  # before any stat of it (which would fail)
        raise ParameterError(
            f"{name}: file name of {len(os.fsencode(p.name))} bytes is longer than the {limit} "
            f"the file system allows: {str(p)!r}"
        )
    target = _resolve(p)
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise ParameterError(f"{name}: {str(p)!r}: directory {str(parent)!r} does not exist")
    if target.is_dir():
        raise ParameterError(f"{name}: {str(p)!r} is a directory; expected a file name")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ParameterError(f"{name}: {str(p)!r}: directory {str(parent)!r} is not writable")
    return target


def _temp_suffix(target: Path) -> str:
    # Writers that pick a format from the name (Pillow, nibabel) need the suffix; keep
    # ".nii.gz" whole, otherwise only the last one (a dotted stem must not lengthen it).
    return ".nii.gz" if target.name.lower().endswith(".nii.gz") else target.suffix


def _clean_stale(folder: Path) -> None:
    """Remove temporaries left in ``folder`` by processes that no longer run."""
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    for entry in entries:
        m = _TEMP_RE.match(entry.name)
        if m is None or not entry.is_file(follow_symlinks=False):
            continue
        pid = int(m.group("pid"))
        if pid == os.getpid():
            continue  # another write of this process, maybe in another thread
        try:
            os.kill(pid, 0)
            continue  # its writer is alive
        except ProcessLookupError:
            pass
        except (PermissionError, OverflowError, OSError):
            continue
        with contextlib.suppress(OSError):
            os.unlink(entry.path)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    If the body raises, the temporary file is removed and ``path`` is untouched, so
    a failed or interrupted write never leaves a partial output behind. A symlink
    at ``path`` is written through (its target is replaced, the link kept).

    Raises
    ------
    ParameterError
        The folder does not exist.
    FileFormatError
        The write failed (disk full, read-only file system, permission): one line
        naming the file and the reason.

    Examples
    --------
    >>> with atomic_path("out.png") as tmp:      # doctest: +SKIP
    ...     image.save(tmp)
    """
    shown = Path(path)
    target = _resolve(shown)
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise ParameterError(f"output {str(shown)!r}: directory {str(parent)!r} does not exist")
    _clean_stale(parent)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f"{TEMP_PREFIX}{os.getpid()}-",
                                        suffix=".part" + _temp_suffix(target), dir=parent)
    except OSError as exc:
        raise _write_error(shown, exc) from exc
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        # mkstemp creates the file 0600; give the output the mode a plain open()
        # would (or the mode of the file it replaces), so reports stay readable.
        with contextlib.suppress(FileNotFoundError):
            os.chmod(tmp, _output_mode(target))
        os.replace(tmp, target)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise _write_error(shown, exc) from exc
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _write_error(path: Path, exc: OSError) -> FileFormatError:
    reason = exc.strerror or str(exc) or type(exc).__name__
    return FileFormatError(f"{str(path)!r}: cannot write: {reason}")


def _output_mode(target: Path) -> int:
    try:
        return target.stat().st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask
