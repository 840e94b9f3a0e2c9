"""Atomic outputs: all or nothing, with ordinary file permissions."""

from __future__ import annotations

import os
import stat

import pytest

from sparsecast._util.atomic import atomic_path
from sparsecast.errors import ParameterError


def test_failed_write_leaves_target_and_no_temporary(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_new_file_gets_umask_mode_not_0600(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_path(tmp_path / "report.md") as tmp:
            tmp.write_text("# report")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "report.md").stat().st_mode) == 0o644


def test_replaced_file_keeps_its_mode(tmp_path):
    target = tmp_path / "fig.png"
    target.write_bytes(b"x")
    target.chmod(0o640)
    with atomic_path(target) as tmp:
        tmp.write_bytes(b"y")
    assert target.read_bytes() == b"y"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640


def test_missing_directory_is_named(tmp_path):
    with pytest.raises(ParameterError, match="does not exist"):
        with atomic_path(tmp_path / "nope" / "a.png"):
            pass
