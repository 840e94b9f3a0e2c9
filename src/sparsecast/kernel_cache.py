"""A Numba kernel cache that cannot go stale.

Numba's ``cache=True`` keys a cached kernel on its own source file's time stamp,
so editing an ``@njit`` helper inlined from *another* module (every kernel here
inlines :mod:`sparsecast.kernels` and the indices' traversals) leaves the caller's
cached machine code in place, running the old helper. Before the first kernel
is compiled, this module points Numba's cache at a folder named after a hash of
every package source that uses Numba (and Numba's version), so any such edit
selects a fresh folder and recompiles everything once.

Where: ``$SPARSECAST_CACHE_DIR``, else ``$NUMBA_CACHE_DIR``, else
``$XDG_CACHE_HOME/sparsecast`` (``~/.cache/sparsecast``), in a subfolder
``kernels-<hash>``. Folders of other hashes unused for :data:`PRUNE_DAYS` days are
removed. ``SPARSECAST_CACHE_DIR=off`` leaves Numba's own default (``__pycache__``
beside the sources). An unwritable location falls back to that default too.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import shutil
import time
from collections.abc import Callable
from pathlib import Path

__all__ = ["configure", "source_hash", "cache_dir", "compile_seconds", "compile_note", "announce_first_compile"]

#: folders of other source hashes older than this are deleted
PRUNE_DAYS = 14

_PACKAGE = Path(__file__).resolve().parent
_configured: Path | None = None


def source_hash(root: Path | None = None) -> str:
    """Hash of every module of the package (or of ``root``) that uses Numba, and of Numba's version."""
    import numba

    root = _PACKAGE if root is None else Path(root)
    h = hashlib.sha256(numba.__version__.encode())
    for path in sorted(root.rglob("*.py")):
        text = path.read_bytes()
        if b"numba" in text:
            h.update(path.relative_to(root).as_posix().encode())
            h.update(b"\0")
            h.update(text)
    return h.hexdigest()[:16]


#: set beside ``NUMBA_CACHE_DIR`` by :func:`configure`, so that a subprocess knows that
#: folder for one of ours (already ``kernels-<hash>``), not a base to nest another in
_OWN_FOLDER = "SPARSECAST_KERNEL_FOLDER"


def _base() -> Path | None:
    for var in ("SPARSECAST_CACHE_DIR", "NUMBA_CACHE_DIR"):
        value = os.environ.get(var)
        if value:
            if var == "SPARSECAST_CACHE_DIR" and value.lower() == "off":
                return None
            if var == "NUMBA_CACHE_DIR" and value == os.environ.get(_OWN_FOLDER):
                # Inherited from a parent's configure(): its base is the folder's parent
                # (without this, every subprocess compiled into a nested, cold folder).
                return Path(value).parent
            return Path(value)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "sparsecast"


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".probe-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
        return True
    except OSError:
        return False


def _prune(base: Path, keep: Path) -> None:
    cutoff = time.time() - PRUNE_DAYS * 86400
    try:
        for other in base.glob("kernels-*"):
            if other != keep and other.is_dir() and other.stat().st_mtime < cutoff:
                shutil.rmtree(other, ignore_errors=True)
    except OSError:
        pass


def configure() -> Path | None:
    """Point Numba's cache at the folder for the current sources (idempotent).

    Returns the folder, or None when Numba's default is kept. Must run before
    the first ``@njit(cache=True)`` function is defined: Numba picks the cache
    location when a function is decorated.
    """
    global _configured
    if _configured is not None:
        return _configured
    _install_compile_clock()
    base = _base()
    if base is None:
        return None
    folder = base / f"kernels-{source_hash()}"
    if not _writable(folder):
        return None
    os.utime(folder)  # the folder's mtime says when it was last used (see _prune)
    _prune(base, folder)
    from numba.core import config

    config.CACHE_DIR = str(folder)
    os.environ["NUMBA_CACHE_DIR"] = str(folder)  # the same folder for subprocesses
    os.environ[_OWN_FOLDER] = str(folder)
    _tolerate_foreign_indexes()
    _serialise_saves(folder)
    _configured = folder
    return folder


def _tolerate_foreign_indexes() -> None:
    """Read a cache index that names types this process cannot import as empty.

    A kernel's cache index pickles the signatures of every overload compiled into
    it, so one compiled for a record type of a module that is not importable here
    (the test suite's ``test-bbox`` index, a user's own index in a script) made
    every later load of that kernel raise ``ModuleNotFoundError``. Treated as a
    cache miss, the kernel compiles again and Numba writes a fresh index.
    """
    try:
        from numba.core.caching import IndexDataCacheFile
    except ImportError:  # another Numba layout: keep its behaviour
        return
    load = IndexDataCacheFile._load_index
    if getattr(load, "_sparsecast_tolerant", False):
        return

    def _load_index(self):
        try:
            return load(self)
        except (ImportError, AttributeError, EOFError, pickle.UnpicklingError):
            return {}

    _load_index._sparsecast_tolerant = True  # type: ignore[attr-defined]
    IndexDataCacheFile._load_index = _load_index


#: in the cache folder: held while a kernel is saved (see _serialise_saves)
SAVE_LOCK = ".save.lock"


def _serialise_saves(folder: Path) -> None:
    """Save one kernel at a time across the processes that share ``folder``.

    Numba saves a kernel by reading its cache index, taking the first free data-file
    number, writing the index back and then the data file, with no lock. Two processes
    saving two specialisations of one kernel at once (pytest-xdist workers, ``sparsecast
    compile --jobs``, Dask workers on one machine) could both take number 1: one
    index entry is lost, or worse, left naming a data file that holds the other's
    machine code, which a later process would load for the wrong argument types.
    An exclusive ``flock`` on one file of the folder around each save rules that out;
    a save takes milliseconds, against seconds of compiling, so nobody waits long.
    Loads need no lock: every file is written whole and renamed into place.
    """
    try:
        import fcntl

        from numba.core.caching import IndexDataCacheFile
    except ImportError:  # no flock (Windows) or another Numba layout: keep its behaviour
        return
    save = getattr(IndexDataCacheFile.save, "_sparsecast_unlocked", IndexDataCacheFile.save)
    lock_path = folder / SAVE_LOCK

    def _save(self, key, data):
        try:
            fh = open(lock_path, "a")
        except OSError:  # the folder went read-only: save as Numba would
            return save(self, key, data)
        with fh:
            fcntl.flock(fh, fcntl.LOCK_EX)  # released when fh is closed
            return save(self, key, data)

    _save._sparsecast_unlocked = save  # type: ignore[attr-defined]
    IndexDataCacheFile.save = _save


def cache_dir() -> Path | None:
    """The folder configured by :func:`configure` (None: Numba's default)."""
    return _configured


# -- how long this process spent compiling ------------------------------------------
_clock = None


def _install_compile_clock() -> None:
    """Count the time of Numba's ``numba:compile`` events (idempotent).

    Numba fires that event only when it compiles, after a cache lookup failed, so
    a start served by the on-disk cache adds nothing. Nested compilations (a
    kernel's callees) are counted once, in the outermost event; Numba compiles
    under one global lock, so the events of different threads never interleave.
    """
    global _clock
    if _clock is not None:
        return
    from numba.core import event

    class _CompileClock(event.Listener):
        def __init__(self) -> None:
            self.seconds = 0.0
            self._depth = 0
            self._t0 = 0.0

        def on_start(self, ev) -> None:
            if self._depth == 0:
                self._t0 = time.perf_counter()
                _announce_once()
            self._depth += 1

        def on_end(self, ev) -> None:
            self._depth -= 1
            if self._depth == 0:
                self.seconds += time.perf_counter() - self._t0

    _clock = _CompileClock()
    event.register("numba:compile", _clock)


_announce: Callable[[], None] | None = None


def announce_first_compile(note: Callable[[], None] | None) -> None:
    """Call ``note()`` once, as this process starts compiling its first kernel (a cache miss).

    The command line tells a user at a terminal why the first render of an index and
    dtype takes a minute where later ones take a second (see :func:`sparsecast.cli.main`).
    None withdraws a note not yet given. Nothing is called when every kernel comes from
    the cache; an exception from ``note`` is ignored (compiling goes on).
    """
    global _announce
    _install_compile_clock()
    _announce = note


def _announce_once() -> None:
    global _announce
    note, _announce = _announce, None
    if note is not None:
        try:
            note()
        except Exception:  # a note must never stop a compile
            pass


def compile_seconds() -> float:
    """Seconds this process has spent compiling kernels (cache loads not included).

    Take the difference around a piece of work to report its compilation apart
    (``sparsecast render`` prints it as ``compile N ms``).
    """
    _install_compile_clock()
    return _clock.seconds  # type: ignore[union-attr]


#: compilation shorter than this is not worth a word in a status line
NOTE_MS = 50.0


def compile_note(seconds: float) -> str:
    """``"compile 1234 ms"`` for ``seconds`` of compilation, ``""`` when there was none to speak of."""
    ms = seconds * 1e3
    return f"compile {ms:.0f} ms" if ms >= NOTE_MS else ""
