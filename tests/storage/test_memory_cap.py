"""A lazy volume renders under a memory cap several times smaller than its dense size.

A child process warms up every kernel, then caps its own data segment
(``RLIMIT_DATA``: heap and anonymous mappings, which is where every NumPy array
lives) at its current size plus a headroom of under a quarter of the dense volume;
it proves the cap bites (the dense array cannot be allocated), then opens a Zarr
store lazily under ``memory_limit`` and renders. The parent renders the dense
volume without a cap, and the images must be the same.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import sparsecast as sc

zarr = pytest.importorskip("zarr")

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_DATA and /proc are Linux's")

N = 448  # 448^3 float32: 343 MiB dense
HEADROOM = 80 << 20  # measured: scan blocks in flight, zarr buffers and the 24 MB pool take ~62 MiB
INDICES = ("kdtree-deep", "naive")

CHILD = textwrap.dedent("""
    import os, resource, sys, tempfile, threading
    threading.stack_size(1 << 20)  # thread stacks are anonymous mappings: they count too
    import numpy as np
    import zarr
    import sparsecast as sc

    store, out, headroom = sys.argv[1], sys.argv[2], int(sys.argv[3])
    indices = sys.argv[4].split(",")
    tf = sc.TransferFunction.preset("hot", (0.0, 1.0), threshold=0.2)
    # Warm up (compile or load) every kernel the capped part runs, on a tiny store.
    a = np.zeros((20, 20, 20), np.float32)
    a[5:9, 5:9, 5:9] = 0.5
    tiny = os.path.join(tempfile.mkdtemp(), "tiny.zarr")
    zarr.create_array(tiny, shape=a.shape, chunks=(8, 8, 8), dtype="float32")[:] = a
    for index in indices:
        w = sc.load_volume(tiny, lazy=True, memory_limit="1MB")
        sc.render(w, tf, sc.Camera.orbit(w), 4, 4, index=index, shading=True)

    def vm_data():
        for line in open("/proc/self/status"):
            if line.startswith("VmData:"):
                return int(line.split()[1]) * 1024

    base = vm_data()
    resource.setrlimit(resource.RLIMIT_DATA, (base + headroom, resource.RLIM_INFINITY))
    vol = sc.load_volume(store, lazy=True, memory_limit="24MB")
    try:
        np.ones(vol.shape, np.float32)
        print("the cap did not bite")
        sys.exit(3)
    except MemoryError:
        pass
    cam = sc.Camera.orbit(vol, 30, 20)
    imgs = [sc.render(vol, tf, cam, 48, 48, index=ix, shading=True).rgba for ix in indices]
    np.save(out, np.stack(imgs))
    print("resident", vol.resident_bricks, "of", vol.stored_bricks, "grew", (vm_data() - base) >> 20, "MiB")
""")


def _halo_store(path) -> np.ndarray:
    """A sparse float32 field of Gaussian halos, written blob by blob into a Zarr store
    (empty chunks never written, as zarr leaves them); returns the dense copy."""
    rng = np.random.default_rng(0)
    dense = np.zeros((N, N, N), np.float32)
    for c, s in zip(rng.uniform(24, N - 24, (40, 3)), rng.uniform(3, 8, 40)):
        lo = np.maximum(np.floor(c - 3 * s).astype(int), 0)
        hi = np.minimum(np.ceil(c + 3 * s).astype(int) + 1, N)
        z, y, x = np.ogrid[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]]
        d2 = (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2
        dense[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]] += np.where(d2 < 9 * s * s, np.exp(-d2 / (2 * s * s)), 0)
    arr = zarr.create_array(str(path), shape=dense.shape, chunks=(64, 64, 64), dtype="float32")
    for k in range(0, N, 64):
        for j in range(0, N, 64):
            for i in range(0, N, 64):
                block = dense[k:k + 64, j:j + 64, i:i + 64]
                if block.any():
                    arr[k:k + 64, j:j + 64, i:i + 64] = block
    return dense


def test_lazy_volume_renders_under_a_memory_cap(tmp_path):
    store = tmp_path / "halos.zarr"
    dense = _halo_store(store)
    assert HEADROOM * 4 < dense.nbytes  # the cap is several times smaller than the volume
    out = tmp_path / "images.npy"
    env = {**os.environ, "MALLOC_ARENA_MAX": "2", "OMP_STACKSIZE": "1M"}
    proc = subprocess.run([sys.executable, "-c", CHILD, str(store), str(out), str(HEADROOM), ",".join(INDICES)],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr[-3000:]
    vol = sc.Volume(dense)
    tf = sc.TransferFunction.preset("hot", (0.0, 1.0), threshold=0.2)
    cam = sc.Camera.orbit(vol, 30, 20)
    want = np.stack([sc.render(vol, tf, cam, 48, 48, index=ix, shading=True).rgba for ix in INDICES])
    got = np.load(out)
    assert np.abs(got - want).max() <= 1e-5
    assert (want[..., 3] > 0.05).any()  # the halos show
