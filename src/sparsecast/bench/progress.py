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

from ..errors import FileFormatError

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
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if fresh and self.path.exists():
            self.path.unlink()
        if self.path.exists():
            self._load()
            self.resumed = len(self.records)

    def _load(self) -> None:
        assert self.path is not None
        text = self.path.read_text()
        lines = text.splitlines()
        for n, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                if n == len(lines) and not text.endswith("\n"):
                    # A line cut short by a kill: drop it (that case runs again) so the
                    # next record starts on a line of its own.
                    with open(self.path, "r+") as f:
                        f.truncate(len(text.encode()) - len(line.encode()))
                    return
                raise FileFormatError(
                    f"journal {str(self.path)!r}: line {n} is not JSON; expected one record per line "
                    "(delete the file or pass --fresh to start over)"
                ) from None
            self._remember(rec)
        if text and not text.endswith("\n") and self._keys:
            with open(self.path, "a") as f:  # the last record made it, its newline did not
                f.write("\n")

    def _remember(self, rec: dict[str, Any]) -> None:
        self.records.append(rec)
        if not rec.get("section"):  # a section is done by its marker, not by its records
            self._keys.add(case_key(rec))

    def done(self, **fields: Any) -> bool:
        """Whether the case with these key fields is already recorded."""
        return case_key(**fields) in self._keys

    def add(self, rec: dict[str, Any]) -> None:
        """Keep ``rec`` and append it to the journal (flushed to disk)."""
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
