"""Outputs under stress (issue 14, item 7): checked before any work, long names, symlinks
written through, write failures as one error, no temporary left behind."""

from __future__ import annotations

import errno
import os
import subprocess
import sys

import numpy as np
import pytest

import sparsecast as sc
from sparsecast._util import atomic
from sparsecast._util.atomic import TEMP_PREFIX, atomic_path, check_output
from sparsecast.errors import FileFormatError, ParameterError

from cli_runner import run_cli


def _img():
    return sc.Image(np.zeros((4, 4, 4), np.float32))


def test_longest_valid_name_works(tmp_path):
    target = tmp_path / ("a" * 240 + ".png")  # 244 characters
    _img().save(target)
    assert target.is_file()
    assert [p.name for p in tmp_path.iterdir()] == [target.name]
    with pytest.raises(ParameterError, match="longer than the 255"):
        check_output(tmp_path / ("a" * 252 + ".png"), "-o")


def test_symlink_is_written_through(tmp_path):
    real = tmp_path / "real.png"
    real.write_bytes(b"old")
    link = tmp_path / "link.png"
    link.symlink_to(real)
    _img().save(link)
    assert link.is_symlink() and real.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS])
def test_write_failure_is_one_error_and_leaves_nothing(tmp_path, monkeypatch, code):
    (tmp_path / "out.png").write_bytes(b"old")

    def failing(self, fp, *args, **kwargs):
        with open(fp, "wb") as fh:
            fh.write(b"partial")
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr("PIL.Image.Image.save", failing)
    with pytest.raises(FileFormatError, match=rf"out.png': cannot write: {os.strerror(code)}$"):
        _img().save(tmp_path / "out.png")
    assert (tmp_path / "out.png").read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


def test_replace_failure_leaves_no_part_file(tmp_path, monkeypatch):
    def no_replace(src, dst):
        raise OSError(errno.EXDEV, "Invalid cross-device link")

    monkeypatch.setattr(atomic.os, "replace", no_replace)
    with pytest.raises(FileFormatError, match="cannot write"):
        with atomic_path(tmp_path / "x.txt") as tmp:
            tmp.write_text("x")
    assert list(tmp_path.iterdir()) == []


def test_stale_temporaries_are_removed_on_the_next_write(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    stale = tmp_path / f"{TEMP_PREFIX}{dead}-abcdefgh.part.png"
    alive = tmp_path / f"{TEMP_PREFIX}{os.getppid()}-abcdefgh.part.png"
    other = tmp_path / ".notours.part.png"
    for p in (stale, alive, other):
        p.write_bytes(b"x")
    with atomic_path(tmp_path / "out.txt") as tmp:
        assert tmp.name.startswith(TEMP_PREFIX) and tmp.name.endswith(".part.txt")
        tmp.write_text("done")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([alive.name, other.name, "out.txt"])


def test_cli_checks_every_output_before_any_work(monkeypatch, capsys, tmp_path):
    out = tmp_path / "out.png"
    out.write_bytes(b"old")
    (tmp_path / "d.png").mkdir()
    missing = str(tmp_path / "nope.nrrd")  # never loaded: the outputs fail first
    code, _, err = run_cli(monkeypatch, capsys, "render", missing, "-o", str(out), "--array", str(tmp_path / "out.txt"))
    assert code == 2 and "--array" in err and ".npy" in err
    assert out.read_bytes() == b"old"
    for args, word in ((["-o", str(tmp_path / "x.xyz")], "-o"),
                       (["-o", str(tmp_path / "no" / "x.png")], "does not exist"),
                       (["-o", str(tmp_path / "d.png")], "is a directory"),
                       (["-o", str(tmp_path / ("b" * 300 + ".png"))], "longer than")):
        code, _, err = run_cli(monkeypatch, capsys, "render", missing, *args)
        assert code == 2 and word in err and "nope.nrrd" not in err, err
        assert len(err.strip().splitlines()) == 1
