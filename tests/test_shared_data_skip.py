"""Tests that need the real data skip with a message naming the folder and the variable."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent


def test_missing_data_skip_names_folder_and_variable(tmp_path):
    empty = tmp_path / "no-data-here"
    env = {**os.environ, "SPARSECAST_DATA": str(empty)}
    res = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider",
         str(TESTS / "io" / "test_meshes.py::test_shared_bunny_loads")],
        env=env, capture_output=True, text=True, timeout=120, cwd=TESTS.parent)
    assert res.returncode == 0, res.stdout + res.stderr
    skip = next(line for line in res.stdout.splitlines() if line.startswith("SKIPPED"))
    assert "stanford_bunny.ply" in skip and str(empty) in skip and "SPARSECAST_DATA" in skip, skip
