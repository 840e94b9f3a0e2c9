"""Concurrent renders and index builds from several threads, under every threading layer.

Numba's ``workqueue`` layer aborts the process when two threads enter parallel
kernels at once; sparsecast serialises its parallel sections under it
(``kernels.parallel``) and renders through its own thread pool.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

import sparsecast as sc
from synthetic import sparse_volume

CODE = r"""
import threading, numpy as np, sparsecast as sc, numba
rng = np.random.default_rng(1)
vols = [sc.Volume((rng.random((40, 36, 44)) * (rng.random((40, 36, 44)) < 0.2)).astype(np.float32))
        for _ in range(2)]
errors = []
def work(vol):
    try:
        for threshold in (0.1, 0.3, 0.5, 0.7):
            tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=threshold)
            for name in ("kdtree-deep", "lbvh", "grid-pc"):
                sc.render(vol, tf, sc.Camera.orbit(vol, 30, 20), 48, 48, index=name)
            ps = sc.datasets.nbody_particles(2000)
            sc.render_particles(ps, sc.Camera.orbit(ps), 24, 24)
    except BaseException as exc:
        errors.append(repr(exc))
threads = [threading.Thread(target=work, args=(v,)) for v in vols]
[t.start() for t in threads]; [t.join() for t in threads]
assert not errors, errors
print(numba.threading_layer())
"""


def test_threads_under_the_workqueue_layer():
    env = dict(os.environ, NUMBA_THREADING_LAYER="workqueue")
    out = subprocess.run([sys.executable, "-c", CODE], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().endswith("workqueue")


def test_concurrent_renders_equal_serial_ones():
    import threading

    rng = np.random.default_rng(2)
    vol = sparse_volume(rng, (30, 28, 32), 8)
    tf = sc.TransferFunction.preset("magma", (0.0, 1.0), threshold=0.2)
    cams = [sc.Camera.orbit(vol, az, 15) for az in (0, 60, 120, 180)]
    serial = [sc.render(vol, tf, c, 40, 30, index="kdtree-deep").rgba for c in cams]
    got = [None] * len(cams)

    def one(i):
        got[i] = sc.render(vol, tf, cams[i], 40, 30, index="kdtree-deep").rgba

    threads = [threading.Thread(target=one, args=(i,)) for i in range(len(cams))]
    [t.start() for t in threads]
    [t.join() for t in threads]
    for a, b in zip(serial, got):
        assert np.array_equal(a, b)
