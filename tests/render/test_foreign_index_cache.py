"""A record class from outside the package must not poison the shared kernel cache.

Numba's cache index pickles every signature of a function; a signature holding a
class that a later process cannot import makes every later cache load of that
function fail. Records defined outside ``sparsecast`` therefore go to an
uncached copy of the driver.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

RENDER = (
    "import sys; sys.path.insert(0, {path!r})\n"
    "import numpy as np, sparsecast as sc\n"
    "vol = sc.Volume(np.random.default_rng(0).random((9, 10, 11)).astype(np.float32))\n"
    "tf = sc.TransferFunction.preset('viridis', (0.0, 1.0))\n"
    "{extra}\n"
    "img = sc.render(vol, tf, sc.Camera.orbit(vol), 6, 6, index={index!r})\n"
    "print(img.stats['samples'])\n"
)


def _run(code: str, cache: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "SPARSECAST_CACHE_DIR")}
    env["SPARSECAST_CACHE_DIR"] = str(cache)
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)


def test_foreign_record_leaves_the_cache_loadable(tmp_path):
    mod = tmp_path / "mods"
    mod.mkdir()
    shutil.copy(HERE.parent / "index" / "bbox_index.py", mod / "foreign_index.py")
    cache = tmp_path / "cache"
    first = _run(RENDER.format(path=str(mod), extra="import foreign_index", index="test-bbox"), cache)
    assert first.returncode == 0, first.stderr
    # A process that cannot import foreign_index loads the same cache.
    second = _run(RENDER.format(path=str(tmp_path / "nothing"), extra="", index="naive"), cache)
    assert second.returncode == 0, second.stderr
    assert int(second.stdout.split()[-1]) > 0
