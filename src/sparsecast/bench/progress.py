"""Resumable benchmark runs: a JSONL journal of finished cases and a progress line.

Every measurement becomes one JSON line appended (and flushed) the moment it is
taken, so an interrupted run loses nothing it finished. Re-running the same
command with the same journal skips every case whose key is already there.
A case key is ``(dataset, tf, method, width, height, view, phase)``.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from .._util.atomic import atomic_path
from ..errors import FileFormatError
from ..io.files import require_regular_file

__all__ = ["CaseKey", "ResultStore", "Progress", "case_key"]

CaseKey = tuple[Any, ...]
_KEY_FIELDS = ("dataset", "tf", "method", "width", "height", "view", "phase")


def case_key(record: dict[str, Any] | None = None, **fields: Any) -> CaseKey:
    """The identity of a measurement: the fields of :data:`_KEY_FIELDS` (missing = None)."""
    merged = {**(record or {}), **fields}
    return tuple(merged.get(f) for f in _KEY_FIELDS)


class ResultStore:
    """Records of one run, mirrored to an append-only JSONL journal.

    Parameters
    ----------
    journal : path or None
        The JSONL file. Existing lines are loaded (a run resumes); ``None`` keeps
        the records in memory only.
    fresh : bool
        Discard an existing journal instead of resuming from it.
    """

    def __init__(self, journal: str | os.PathLike | None = None, *, fresh: bool = False) -> None:
        self.path = None if journal is None else Path(journal)
        self.records: list[dict[str, Any]] = []
        self._keys: set[CaseKey] = set()
        self.resumed = 0
        if self.path is None:
            return
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:  # e.g. --json under a path that is a file
            raise FileFormatError(
                f"journal {str(self.path)!r}: cannot create its folder {str(self.path.parent)!r} "
                f"({exc.strerror or exc}); expected a folder path"
            ) from None
        if fresh and self.path.exists():
            self.path.unlink()
        if self.path.exists() or self.path.is_symlink():
            require_regular_file(self.path, "benchmark journal (JSON lines)")
            self._load()
            self.resumed = len(self.records)

    def _load(self) -> None:
        """Read the journal; keep each case once and each section only with its marker.

        A kill can cut the last line (dropped: that case runs again) or a section's
        block of records (a section is journaled with one write, but a write can be
        cut): records of a section without its ``section_done`` marker are dropped,
        so the section reruns without duplicating them. When anything is dropped the
        journal is rewritten (atomically) with what is kept.
        """
        assert self.path is not None
        data = self.path.read_bytes()
        cut = bool(data) and not data.endswith(b"\n")
        lines = data.split(b"\n")
        if lines and lines[-1] == b"":
            lines.pop()
        kept: list[dict[str, Any]] = []
        pending: dict[Any, list[dict[str, Any]]] = {}  # section name -> its records so far
        dirty = cut
        for n, raw in enumerate(lines, 1):
            if not raw.strip():
                continue
            rec = self._parse_line(raw, n, last=cut and n == len(lines))
            if rec is None:
                continue
            if rec.get("section"):
                pending.setdefault(rec["section"], []).append(rec)
                continue
            key = case_key(rec)
            is_marker = rec.get("phase") == "section_done"
            if key in self._keys:  # a case twice (a duplicated journal): keep the first
                dirty = True
                if is_marker:
                    pending.pop(rec.get("method"), None)  # the section's second copy
                continue
            if is_marker:
                kept.extend(pending.pop(rec.get("method"), []))
            self._keys.add(key)
            kept.append(rec)
        if any(pending.values()):
            dirty = True  # a section cut inside its block: it runs again, in full
        self.records = kept
        if dirty:
            with atomic_path(self.path) as tmp:
                tmp.write_text("".join(json.dumps(r, default=_jsonable) + "\n" for r in kept))

    def _parse_line(self, raw: bytes, n: int, *, last: bool) -> dict[str, Any] | None:
        """One journal line as a record; None for a last line cut short by a kill."""
        where = f"journal {str(self.path)!r}: line {n}"
        hint = "; expected one JSON object per line (delete the file or pass --fresh to start over)"
        try:
            rec = json.loads(raw.decode("utf-8"))
        except UnicodeDecodeError:
            if last:
                return None
            raise FileFormatError(f"{where} is not UTF-8 text{hint}") from None
        except (RecursionError, ValueError):  # JSONDecodeError is a ValueError
            if last:
                return None
            raise FileFormatError(f"{where} is not JSON{hint}") from None
        if not isinstance(rec, dict):
            raise FileFormatError(f"{where} is a JSON {type(rec).__name__}, not an object{hint}")
        for field in _KEY_FIELDS + ("section",):
            value = rec.get(field)
            if value is not None and not isinstance(value, (str, int, float, bool)):
                raise FileFormatError(
                    f"{where}: field {field!r} is a JSON {type(value).__name__}; expected a string, "
                    f"number or null{hint}"
                )
        return rec

    def _remember(self, rec: dict[str, Any]) -> None:
        self.records.append(rec)
        if not rec.get("section"):  # a section is done by its marker, not by its records
            self._keys.add(case_key(rec))

    def done(self, **fields: Any) -> bool:
        """Whether the case with these key fields is already recorded."""
        return case_key(**fields) in self._keys

    def add(self, rec: dict[str, Any]) -> None:
        """Keep ``rec`` and append it to the journal (flushed to disk); a case already
        recorded is not recorded again."""
        if not rec.get("section") and case_key(rec) in self._keys:
            return
        self._remember(rec)
        self.extend_journal([rec])

    def note(self, rec: dict[str, Any]) -> None:
        """Keep ``rec`` for this run's output only (not journalled, no case key): e.g.
        "peer skipped: not installed", which a later run should try again."""
        self.records.append(rec)

    def add_many(self, recs: Iterable[dict[str, Any]]) -> None:
        """Keep several records and append them to the journal in one write (a section
        that must not be half-recorded)."""
        recs = list(recs)
        for r in recs:
            self._remember(r)
        self.extend_journal(recs)

    def extend_journal(self, recs: list[dict[str, Any]]) -> None:
        if self.path is None or not recs:
            return
        text = "".join(json.dumps(r, default=_jsonable) + "\n" for r in recs)
        with open(self.path, "a") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())


def _jsonable(value: Any) -> Any:
    """NumPy scalars and other number-likes as plain JSON numbers."""
    try:
        return value.item()
    except AttributeError:
        return float(value)


class Progress:
    """Cases done / total and the ETA, drawn with rich on stderr (or silent).

    The ETA extrapolates the mean time of the cases measured *in this session*
    (resumed cases count as done but not towards the rate).
    """

    #: seconds between plain progress lines when the console is not a terminal (a log file)
    LOG_EVERY_S = 30.0

    def __init__(self, total: int, done: int = 0, *, console=None, label: str = "bench") -> None:
        self.total = max(total, done)
        self.done_count = done
        self._session_start = time.perf_counter()
        self._session_done = 0
        self._label = label
        self._message = ""
        self._status = None
        self._console = console
        self._last_log = -float("inf")
        if console is not None and console.is_terminal:
            self._status = console.status(self._line())
            self._status.start()

    def eta_s(self) -> float | None:
        if self._session_done == 0:
            return None
        rate = (time.perf_counter() - self._session_start) / self._session_done
        return rate * (self.total - self.done_count)

    def _line(self) -> str:
        eta = self.eta_s()
        eta_text = "ETA --" if eta is None else f"ETA {_hms(eta)}"
        return f"{self._label}: {self.done_count}/{self.total} cases, {eta_text}  {self._message}"

    def say(self, message: str) -> None:
        self._message = message
        if self._status is not None:
            self._status.update(self._line())
        elif self._console is not None and time.perf_counter() - self._last_log >= self.LOG_EVERY_S:
            self._last_log = time.perf_counter()
            self._console.print(self._line(), highlight=False)

    def advance(self, n: int = 1) -> None:
        self.done_count += n
        self._session_done += n
        self.total = max(self.total, self.done_count)
        self.say(self._message)

    def close(self) -> None:
        if self._status is not None:
            self._status.stop()
            self._status = None


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"
