"""Where the shared real data lives: ``$SPARSECAST_DATA``, else ``../shared/data``.

The benchmark's real volumes (:mod:`.catalog`) and meshes (:mod:`.surface`) are read
from there; a checkout without it runs the generated cases only.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["find_shared_data"]


def find_shared_data() -> Path | None:
    """The shared data folder, or None when this checkout has none.

    Looks at ``$SPARSECAST_DATA`` first, then ``../shared/data`` relative to the
    working directory and to the project root (where ``src/`` lives).
    """
    env = os.environ.get("SPARSECAST_DATA")
    candidates = [Path(env)] if env else []
    project_root = Path(__file__).resolve().parents[3]
    for base in (Path.cwd(), project_root):
        candidates += [base / ".." / "shared" / "data", base / "shared" / "data"]
    for c in candidates:
        if c.is_dir():
            return c.resolve()
    return None
