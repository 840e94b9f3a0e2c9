"""Bench journal robustness (issue 14, item 8): resume never duplicates records, every bad
line is one clear error naming it."""

from __future__ import annotations

import importlib.machinery
import json
import os
import sys
import types

import pytest

from sparsecast.bench import run_benchmarks
from sparsecast.bench.config import BenchConfig
from sparsecast.bench.progress import ResultStore
from sparsecast.errors import FileFormatError


@pytest.fixture
def sec(monkeypatch):
    module = types.ModuleType("sparsecast.bench.jsec")
    module.__spec__ = importlib.machinery.ModuleSpec("sparsecast.bench.jsec", None)
    module.calls = 0

    def run(datasets, *, width, height, repeat, warmup, record):
        module.calls += 1
        for i in range(15):
            record(dataset="mesh", method=f"m{i}", phase="render", ms=float(i))

    module.run = run
    monkeypatch.setitem(sys.modules, "sparsecast.bench.jsec", module)
    return module


def test_section_cut_inside_its_records_reruns_without_keeping_them(sec, tmp_path):
    cfg = BenchConfig(datasets=[], methods=["naive"], sizes=[(8, 8)], repeat=1, warmup=0, irt=False,
                      sections=["jsec"])
    journal = tmp_path / "j.jsonl"
    run_benchmarks(cfg, store=ResultStore(journal))
    lines = journal.read_text().splitlines()
    assert len(lines) == 16  # 15 records + the section's marker
    journal.write_text("\n".join(lines[:7]) + "\n" + lines[7][:20])  # killed inside the block
    records = run_benchmarks(cfg, store=ResultStore(journal))
    assert sec.calls == 2
    assert sum(r.get("section") == "jsec" for r in records) == 15
    assert len(journal.read_text().splitlines()) == 16
    # a journal holding the section twice (e.g. written by an older version) is read once
    journal.write_text("\n".join(lines + lines) + "\n")
    store = ResultStore(journal)
    assert sum(r.get("section") == "jsec" for r in store.records) == 15
    assert len(journal.read_text().splitlines()) == 16


def test_resumed_cases_are_never_added_twice(tmp_path):
    store = ResultStore(tmp_path / "j.jsonl")
    rec = {"dataset": "d", "tf": "t", "method": "naive", "phase": "load", "ms": 1.0}
    store.add(rec)
    store.add({**rec, "ms": 2.0})
    again = ResultStore(tmp_path / "j.jsonl")
    assert [r["ms"] for r in again.records] == [1.0]


@pytest.mark.parametrize("line, message", [
    (b"[1, 2]", "line 2 is a JSON list, not an object"),
    (b"42", "line 2 is a JSON int"),
    (b'{"dataset": [1, 2], "phase": "load"}', "line 2: field 'dataset' is a JSON list"),
    (b'{"view": {"a": 1}}', "line 2: field 'view' is a JSON dict"),
    (b'{"dataset": "\xff\xfe"}', "line 2 is not UTF-8"),
    (b"[" * 100_000, "line 2 is not JSON"),
])
def test_bad_lines_are_named(tmp_path, line, message):
    journal = tmp_path / "j.jsonl"
    journal.write_bytes(b'{"dataset": "d", "phase": "load"}\n' + line + b'\n{"phase": "x"}\n')
    with pytest.raises(FileFormatError, match=message):
        ResultStore(journal)


def test_json_under_a_file_and_fifo_journal(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileFormatError, match="cannot create its folder"):
        ResultStore(tmp_path / "file" / "records.jsonl")
    os.mkfifo(tmp_path / "p.jsonl")
    with pytest.raises(FileFormatError, match="FIFO"):
        ResultStore(tmp_path / "p.jsonl")


def test_cli_json_under_a_file_is_one_line(monkeypatch, capsys, tmp_path):
    from cli_runner import run_cli

    (tmp_path / "file").write_text("x")
    code, _, err = run_cli(monkeypatch, capsys, "bench", "-d", "demo", "-m", "naive",
                           "--json", str(tmp_path / "file" / "r.json"))
    assert code == 2 and "cannot create its folder" in err and "Traceback" not in err
