"""Benchmark section ``distributed``: rendering on a Dask ``LocalCluster`` (issue 18).

The n-body-like field of :mod:`.scale` at :data:`EDGE`^3 float32, written as ``.npy``
(the workers open it themselves through its source recipe), is rendered

- in this process (``single``: ``render`` with a prebuilt index, every core), and
- on a ``LocalCluster`` of :data:`WORKERS` one-thread worker processes, cut into 1, 2
  and 4 pieces (``cluster-<p>``: :class:`~sparsecast.distributed.ClusterVolume`),

with the same TF, camera and lattice, in interleaved rounds (median, min, max of the
client's wall time per frame), for a sparse TF (``tf="sparse"``: a frame of tens of
milliseconds, where the cluster's per-frame overhead shows) and a dense one
(``"dense"``: every sample visible, seconds of marching, where it is amortised). Per case also: the TF-change latency (a new TF: the
single process rebuilds its index and renders, each piece rebuilds its own), bytes
moved per frame, the slowest piece's render ms, and the compositing time of two
full-frame layers against the image size. The image of each case is checked against
the single process (``max_diff``; ``ert=1``, so they agree to rounding).

``phase="model"`` records extrapolate the frame to N machines of this one's kind from
the measured parts of the sparse TF's frames: ``overhead`` (a one-piece cluster frame
minus its piece's render ms: scheduling and transfers), the pieces' render time divided by N at the measured
imbalance of 4 pieces (slowest / mean), and ``log2(pieces)`` compositing levels of a
full frame. It leaves out network bandwidth beyond this machine's loopback.
"""

from __future__ import annotations

import math
import os
import shutil
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = ["run", "EDGE", "WORKERS", "PIECES"]

#: edge of the field (512^3 float32: 512 MiB); SPARSECAST_BENCH_DIST_EDGE overrides
EDGE = 512
#: one-thread worker processes of the LocalCluster
WORKERS = 2
#: piece counts measured
PIECES = (1, 2, 4)
#: index every piece (and the single process) uses
INDEX = "kdtree-deep"


def run(datasets: list[str] | None, *, width: int, height: int, repeat: int, warmup: int,
        record: Callable[..., None], edge: int | None = None, workers: int = WORKERS,
        pieces: tuple[int, ...] = PIECES) -> None:
    """Measure the cases above; ``datasets`` is unused (the section generates its field)."""
    from distributed import Client, LocalCluster, wait

    from ..camera import Camera
    from ..distributed import ClusterVolume, Layer, over
    from ..index import build_index
    from ..io import load_volume
    from ..render import render
    from ..transfer import TransferFunction
    from .scale import write_field

    n = int(edge or os.environ.get("SPARSECAST_BENCH_DIST_EDGE", EDGE))
    work = Path(tempfile.mkdtemp(prefix="sparsecast-dist-"))
    repeat = max(repeat, 3)
    try:
        path = write_field(n, work, kinds=("npy",))["npy"]
        vol = load_volume(path)
        lo, hi = vol.value_range
        cam = Camera.orbit(vol, 30.0, 20.0)
        common = dict(dataset=f"nbody-{n}", width=width, height=height, workers=workers, index=INDEX)
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=40) as cluster, Client(cluster) as client:
            t0 = time.perf_counter()
            cvs = {}
            for p in pieces:
                cvs[p] = ClusterVolume(vol, client, pieces=p)
            for cv in cvs.values():
                wait(cv.futures)
            load_ms = (time.perf_counter() - t0) * 1e3
            last: dict = {}
            frames_sparse: dict = {}
            for label, make in (("sparse", lambda k: TransferFunction.preset("viridis", (lo, hi),
                                                                              threshold=0.02 + 0.01 * k)),
                                ("dense", lambda k: TransferFunction(
                                    [(lo, 0.1, 0.1, 0.4, 0.004 + 0.001 * k), (hi, 1.0, 0.9, 0.3, 0.6)]))):
                tf = make(0)
                idx = build_index(vol, tf, INDEX)

                def single(t, index):
                    w0 = time.perf_counter()
                    img = render(vol, t, cam, width, height, index=index, ert=1.0)
                    return (time.perf_counter() - w0) * 1e3, img

                def clustered(p, t):
                    w0 = time.perf_counter()
                    img = cvs[p].render(t, cam, width, height, index=INDEX, ert=1.0)
                    return (time.perf_counter() - w0) * 1e3, img

                cases = {"single": lambda t: single(t, idx),
                         **{f"cluster-{p}": (lambda t, p=p: clustered(p, t)) for p in pieces}}
                for _ in range(max(warmup, 1)):  # compiles and loads on every worker, builds every index
                    for f in cases.values():
                        f(tf)
                frames: dict[str, list[float]] = {k: [] for k in cases}
                shown = {}
                for _ in range(repeat):  # interleaved rounds, the same TF: indices kept
                    for k, f in cases.items():
                        ms, img = f(tf)
                        frames[k].append(ms)
                        shown[k] = img
                # TF change: a TF no piece has seen in every round, so each frame rebuilds first
                changes: dict[str, list[float]] = {k: [] for k in cases}
                for r in range(repeat):
                    t = make(r + 1)
                    for k, f in cases.items():
                        w0 = time.perf_counter()
                        if k == "single":
                            render(vol, t, cam, width, height, index=build_index(vol, t, INDEX), ert=1.0)
                        else:
                            f(t)
                        changes[k].append((time.perf_counter() - w0) * 1e3)
                ref = shown["single"]
                for k in cases:
                    img = shown[k]
                    st = img.stats
                    rec = dict(common, method=k, phase="frame", tf=label, ms=statistics.median(frames[k]),
                               ms_runs=frames[k], ms_min=min(frames[k]), ms_max=max(frames[k]),
                               ratio_vs_single=statistics.median(frames[k]) / statistics.median(frames["single"]),
                               tf_change_ms=statistics.median(changes[k]), tf_change_runs=changes[k],
                               samples=int(st["samples"]), max_diff=float(np.abs(img.rgba - ref.rgba).max()))
                    if k != "single":
                        rec.update(pieces=st["pieces"], bytes_moved=st["bytes_moved"],
                                   piece_ms_max=st["piece_ms_max"], piece_ms=st["piece_ms"],
                                   composite_ms=st["composite_ms"], submit_ms=st["submit_ms"])
                    else:
                        rec.update(pieces=1, render_ms=st["ms"])
                    record(**rec)
                if label == "sparse":
                    last, frames_sparse = shown, frames
            record(**common, method="load", phase="load", ms=load_ms, pieces=list(pieces))
            # compositing vs image size: two full-frame layers, this process
            rng = np.random.default_rng(0)
            for side in (256, 512, 1024):
                a = [Layer(0, 0, rng.random((side, side, 4), np.float32) * 0.5, np.ones((side, side), np.int32))
                     for _ in range(2)]
                runs = []
                for _ in range(5):
                    w0 = time.perf_counter()
                    over(a[0], a[1])
                    runs.append((time.perf_counter() - w0) * 1e3)
                record(**{**common, "width": side, "height": side}, method="over", phase="composite",
                       ms=statistics.median(runs), ms_runs=runs, bytes=2 * a[0].nbytes)
            # a model of N machines from the measured parts
            one = last["cluster-1"].stats
            overhead = statistics.median(frames_sparse["cluster-1"]) - one["piece_ms_max"]
            top = last[f"cluster-{max(pieces)}"].stats
            mean_piece = statistics.mean(top["piece_ms"]) if top["piece_ms"] else 0.0
            imbalance = top["piece_ms_max"] / mean_piece if mean_piece else 1.0
            work_ms = sum(top["piece_ms"])  # one thread's worth of rendering for the frame
            side_ms = statistics.median(runs)  # the 1024^2 composite, scaled by area below
            comp_ms = side_ms * (width * height) / (1024 * 1024)
            for machines in (1, 2, 4, 8, 16, 32):
                p_total = machines * workers
                t = overhead + work_ms / p_total * imbalance + math.log2(max(p_total, 1)) * comp_ms
                record(**common, method=f"model-{machines}", phase="model", machines=machines,
                       ms=t, overhead_ms=overhead, work_ms=work_ms, imbalance=imbalance, composite_ms=comp_ms)
    finally:
        shutil.rmtree(work, ignore_errors=True)
