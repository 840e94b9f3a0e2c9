"""Run ``sparsecast ...`` in-process through the real entry point (shared by the CLI tests)."""

from __future__ import annotations

import sys

from sparsecast.cli import main


def run_cli(monkeypatch, capsys, *args: str) -> tuple[int, str, str]:
    """Return ``(exit code, stdout, stderr)`` of ``sparsecast ARGS``."""
    monkeypatch.setattr(sys, "argv", ["sparsecast", *args])
    try:
        main()
        code = 0
    except SystemExit as exc:  # typer/click exit, or our error handler
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capsys.readouterr()
    return code, out, err
