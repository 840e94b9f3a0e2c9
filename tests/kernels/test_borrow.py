"""Hot kernels take no references (kernels.borrow.NO_REFCOUNT); the lattice march is
compiled once for every index (index.interval "Inlining")."""

from __future__ import annotations

import re

import numpy as np
from numba import njit
from numba.core.caching import NullCache

import sparsecast as sc
from sparsecast.kernels import iso
from sparsecast.kernels.march import march_interval
from sparsecast.render import driver, local
from synthetic import sparse_volume


def test_march_interval_is_one_copy_for_every_index(monkeypatch):
    """The lattice march's signature names no record: rendering with a second index of
    the same voxel dtype and sampler compiles no new copy of it.

    The driver runs uncached here, so that it is typed in this process (a driver
    loaded from the disk cache never asks for ``march_interval`` by name)."""
    monkeypatch.setattr(local, "tiles_kernel", lambda record: driver.render_chunk_uncached)
    vol = sparse_volume(np.random.default_rng(3), (20, 20, 20), 4)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    cam = sc.Camera.orbit(vol, 30, 20)
    sc.render(vol, tf, cam, 8, 8, index=sc.build_index(vol, tf, "naive"))
    after_first = set(march_interval.signatures)
    assert after_first, "the driver no longer calls march_interval as a function"
    for kind in ("grid-mm", "lbvh"):
        sc.render(vol, tf, cam, 8, 8, index=sc.build_index(vol, tf, kind))
        assert set(march_interval.signatures) == after_first, kind


def _counting_calls(dispatcher, sig, options=None) -> list[str]:
    """Reference counting in ``dispatcher``'s own machine code for ``sig``: calls of the
    runtime's ``NRT_incref`` / ``NRT_decref``, or their atomics where LLVM inlined
    them. A dispatcher without the disk cache is read as it was compiled in this
    process (so is a cached one whose ``sig`` was compiled here, on a cold cache); one
    loaded from the disk cache is compiled again uncached with the same options,
    updated by ``options`` (a copy loaded from the disk cache keeps no assembly)."""
    # Numba marks a library loaded from its disk cache `_disable_inspection`; where the
    # private flag is missing, recompiling is the safe reading.
    compiled_here = not getattr(dispatcher.overloads[sig].library, "_disable_inspection", True)
    if options is None and (isinstance(dispatcher._cache, NullCache) or compiled_here):
        fresh = dispatcher  # its assembly kept: no second compile of a large kernel
    else:
        opts = {k: v for k, v in dispatcher.targetoptions.items() if k not in ("cache", "nopython")} | (options or {})
        fresh = njit(**opts)(dispatcher.py_func)
        fresh.compile(sig)
    asm = fresh.inspect_asm(sig)
    name = fresh.overloads[sig].fndesc.llvm_func_name
    start = asm.index(f"\n{name}:")
    body = asm[start:asm.index(".Lfunc_end", start)]
    return re.findall(r"\bNRT_(?:incref|decref)\b|\block\b", body)


def test_hot_kernels_count_no_references(monkeypatch):
    """The driver's tile loop and the per-interval and per-hit kernels compile without
    reference counting (kernels.borrow.NO_REFCOUNT): a call into the runtime per array
    argument cost 6 % of a k-d tree isosurface frame. The control, one of them compiled
    with the runtime, does count. The driver runs uncached, so that its callees are
    typed in this process (as in the test above)."""
    monkeypatch.setattr(local, "tiles_kernel", lambda record: driver.render_chunk_uncached)
    vol = sparse_volume(np.random.default_rng(5), (16, 16, 16), 3)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.1)
    cam = sc.Camera.orbit(vol, 30, 20)
    sc.render(vol, tf, cam, 8, 8, index="kdtree-deep", mode="iso", iso=0.5)
    sc.render(vol, tf, cam, 8, 8, index="kdtree-deep")
    # iso._refine is an overload; on trilinear volumes it calls _refine_cubic, one
    # specialisation per voxel layout: the bricked one reads its corners from the pages.
    bricked = sc.BrickedVolume(vol.data)
    sc.render(bricked, tf, cam, 8, 8, index="kdtree-deep", mode="iso", iso=0.5)
    # A caller loaded from the disk cache links its own copy and types no callee here:
    # type both layouts' refine directly, so the check below sees them either way.
    nz, ny, nx = vol.data.shape
    bracket = (0.5, 0.5, 0.5, 0.6, 0.0, 0.8, 0.0, 1.0, -0.25, 0.25, 0.5)
    for data in (np.ascontiguousarray(vol.data).reshape(-1), bricked.voxels()):
        iso._refine_cubic(data, nx, ny, nz, *bracket)
    assert len(iso._refine_cubic.signatures) >= 2, "no bricked specialisation of the iso refine"
    for disp in (driver.dvr_tiles_uncached, iso.iso_interval, iso._refine_cubic, march_interval):
        assert disp.signatures, disp.py_func.__name__
        for sig in disp.signatures:
            assert _counting_calls(disp, sig) == [], (disp.py_func.__name__, sig)

    # The control: the same per-interval kernel compiled with the runtime counts.
    assert _counting_calls(iso.iso_interval, iso.iso_interval.signatures[0], {"_nrt": True})
