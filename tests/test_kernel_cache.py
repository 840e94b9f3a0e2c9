"""The kernel cache folder follows the kernel sources, so an edited helper cannot run stale."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import sparsecast
from sparsecast import kernel_cache

PACKAGE = Path(sparsecast.__file__).resolve().parent


def test_hash_changes_with_an_inlined_helper(tmp_path):
    copy = tmp_path / "pkg"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = kernel_cache.source_hash(copy)
    assert before == kernel_cache.source_hash(PACKAGE)
    helper = copy / "kernels" / "sample.py"  # inlined into every marcher
    helper.write_text(helper.read_text() + "\n# an edit\n")
    assert kernel_cache.source_hash(copy) != before
    # Modules without Numba do not count (editing the CLI recompiles nothing).
    copy_cli = next(p for p in copy.rglob("*.py") if b"numba" not in p.read_bytes())
    h = kernel_cache.source_hash(copy)
    copy_cli.write_text(copy_cli.read_text() + "\n# an edit\n")
    assert kernel_cache.source_hash(copy) == h


def _run(code: str, env: dict) -> str:
    full = {k: v for k, v in os.environ.items()
            if k not in ("NUMBA_CACHE_DIR", "SPARSECAST_CACHE_DIR", "SPARSECAST_KERNEL_FOLDER")}
    full.update(env)
    out = subprocess.run([sys.executable, "-c", code], env=full, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_numba_uses_the_hashed_folder(tmp_path):
    code = ("import sparsecast as sc, numpy as np\n"
            "from numba.core import config\n"
            "from sparsecast import kernel_cache as k\n"
            "from sparsecast.kernels.ray import lattice_range\n"
            "lattice_range(0.0, 1.0, 0.5)\n"
            "print(config.CACHE_DIR, '|', k.cache_dir(), '|', lattice_range.stats.cache_path)")
    cfg, configured, used = _run(code, {"SPARSECAST_CACHE_DIR": str(tmp_path)}).split(" | ")
    folder = tmp_path / f"kernels-{kernel_cache.source_hash()}"
    assert Path(cfg) == folder and Path(configured) == folder
    assert Path(used).is_relative_to(folder)
    assert any(folder.rglob("*.nbi"))  # the kernel's cache index landed there


@pytest.mark.parametrize("set_base", [True, False])
def test_a_subprocess_uses_its_parents_folder(tmp_path, set_base):
    """A child inherits NUMBA_CACHE_DIR pointing at the parent's kernels-<hash> folder:
    it must reuse that folder (warm), not nest a cold kernels-<hash> inside it."""
    code = ("import os, subprocess, sys\n"
            "from sparsecast import kernel_cache as k\n"
            "print(k.configure())\n"
            "child = 'from sparsecast import kernel_cache as k; print(k.configure())'\n"
            "print(subprocess.run([sys.executable, '-c', child], capture_output=True, text=True,"
            " check=True).stdout.strip())")
    env = {"SPARSECAST_CACHE_DIR": str(tmp_path)} if set_base else {"XDG_CACHE_HOME": str(tmp_path)}
    parent, child = _run(code, env).splitlines()
    assert Path(parent).name == f"kernels-{kernel_cache.source_hash()}"
    assert Path(parent).is_relative_to(tmp_path)
    assert child == parent


def test_a_users_numba_cache_dir_is_a_base(tmp_path):
    out = _run("from sparsecast import kernel_cache as k; print(k.configure())", {"NUMBA_CACHE_DIR": str(tmp_path)})
    assert Path(out) == tmp_path / f"kernels-{kernel_cache.source_hash()}"


def test_off_keeps_numbas_default(tmp_path):
    out = _run("import sparsecast; from sparsecast import kernel_cache as k; print(k.cache_dir())",
               {"SPARSECAST_CACHE_DIR": "off"})
    assert out == "None"


def test_index_naming_an_unimportable_type_is_a_cache_miss(tmp_path, monkeypatch):
    """A cache index that pickles a type from a module this process cannot import
    (the suite's test-bbox index) reads as empty instead of raising."""
    import importlib

    from numba.core.caching import IndexDataCacheFile

    kernel_cache.configure()
    mod_dir = tmp_path / "mods"
    mod_dir.mkdir()
    (mod_dir / "ghost_record_mod.py").write_text("class Ghost:\n    pass\n")
    monkeypatch.syspath_prepend(str(mod_dir))
    ghost = importlib.import_module("ghost_record_mod")
    cache = IndexDataCacheFile(str(tmp_path / "cache"), "kernel-x", "stamp")
    os.makedirs(tmp_path / "cache", exist_ok=True)
    cache._save_index({("sig", ghost.Ghost): "data-0"})
    assert cache._load_index() == {("sig", ghost.Ghost): "data-0"}
    monkeypatch.delitem(sys.modules, "ghost_record_mod")
    (mod_dir / "ghost_record_mod.py").unlink()
    importlib.invalidate_caches()
    assert cache._load_index() == {}


def test_a_save_waits_for_the_folders_lock(tmp_path):
    """Processes saving specialisations of one kernel at once could both take data file 1
    (pytest-xdist workers, compile --jobs, Dask workers): each save holds an exclusive
    lock on one file of the kernel folder."""
    import fcntl
    import threading

    from numba.core.caching import IndexDataCacheFile

    folder = kernel_cache.configure()
    if folder is None:
        pytest.skip("Numba's default cache location (SPARSECAST_CACHE_DIR=off)")
    cache = IndexDataCacheFile(str(tmp_path), "kernel-y", "stamp")
    saved = threading.Event()

    def save():
        cache.save(("sig", 1), b"machine code")
        saved.set()

    with open(folder / kernel_cache.SAVE_LOCK, "a") as other:  # another process saving, as it were
        fcntl.flock(other, fcntl.LOCK_EX)
        thread = threading.Thread(target=save)
        thread.start()
        assert not saved.wait(0.5)
    thread.join(30)
    assert saved.is_set()
    assert cache.load(("sig", 1)) == b"machine code"
    assert kernel_cache.configure() == folder  # idempotent: the lock is wrapped once
    assert not hasattr(IndexDataCacheFile.save._sparsecast_unlocked, "_sparsecast_unlocked")


def test_first_compile_is_announced_once(monkeypatch):
    from numba import njit

    monkeypatch.setattr(kernel_cache, "_announce", None)
    said = []
    kernel_cache.announce_first_compile(lambda: said.append(1))

    @njit
    def f(x):
        return x + 1

    @njit
    def g(x):
        return f(x) * 2  # a nested compile, then another kernel: still one note

    assert g(1) == 4 and said == [1]
    assert f(1.5) == 2.5 and said == [1]

    kernel_cache.announce_first_compile(lambda: said.append(2))
    kernel_cache.announce_first_compile(None)  # withdrawn before any compile
    assert f(2j) == 1 + 2j and said == [1]

    kernel_cache.announce_first_compile(lambda: 1 / 0)  # a failing note does not stop a compile
    assert f(np.int8(3)) == 4


def test_compile_clock_counts_compilation_only():
    from numba import njit

    @njit  # a fresh function: its first call compiles, later calls do not
    def twice(x):
        return 2 * x

    before = kernel_cache.compile_seconds()
    assert twice(3) == 6
    compiled = kernel_cache.compile_seconds()
    assert compiled > before
    assert twice(4) == 8
    assert kernel_cache.compile_seconds() == compiled


def test_compile_note():
    assert kernel_cache.compile_note(1.2345) == "compile 1234 ms"
    assert kernel_cache.compile_note(0.0) == ""
    assert kernel_cache.compile_note(kernel_cache.NOTE_MS / 2e3) == ""
