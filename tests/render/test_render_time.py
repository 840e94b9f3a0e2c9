"""Bounded render time: a cap on samples per image, frames that stop between pieces, frames
beside other work."""

from __future__ import annotations

import _thread
import signal
import threading
import time

import numba
import numpy as np
import pytest

import sparsecast as sc
from sparsecast import ParameterError
from sparsecast.kernels import parallel
from sparsecast.render import schedule


def test_tiny_dt_is_refused_before_any_work():
    vol = sc.Volume(np.zeros((64, 64, 64), np.float32))
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0))
    cam = sc.Camera.orbit(vol)
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match=r"dt: 0\.0001 at 96x96 pixels .* max_samples"):
        sc.render(vol, tf, cam, 96, 96, dt=1e-4)
    assert time.perf_counter() - t0 < 1.0
    # Asked for explicitly, a bigger budget is allowed (here on a 4x4 image).
    img = sc.render(vol, tf, cam, 4, 4, dt=0.01, max_samples=10**7)
    assert img.rgba.shape == (4, 4, 4)
    with pytest.raises(ParameterError, match="max_samples"):
        sc.render(vol, tf, cam, 4, 4, max_samples=0)


def test_an_interrupt_stops_the_frame_between_chunks(monkeypatch):
    """Ctrl-C while a frame renders: KeyboardInterrupt within a chunk, the rest cancelled."""
    monkeypatch.setattr(schedule, "n_threads", lambda: 2)
    # Ctrl-C as Python delivers it (another library in the process may have replaced the
    # handler, and interrupt_main does nothing without Python's own).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    calls = []

    def slow_chunk(first, last):
        calls.append(first)
        if len(calls) == 3:  # Ctrl-C during the frame, from a worker (no timer to race)
            _thread.interrupt_main()
        time.sleep(0.05)

    t0 = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            schedule.run_tiles(slow_chunk, 8 * 64, 8 * 64)  # 4096 tiles, 32 chunks of 0.05 s: 0.8 s
    finally:
        signal.signal(signal.SIGINT, previous)
    waited = time.perf_counter() - t0
    assert waited < 0.5
    time.sleep(0.15)  # chunks already running finish; the others were cancelled
    assert len(calls) < 32


def test_a_frame_renders_while_the_helper_pool_is_busy():
    """A frame beside other work in the shared helper pool (an index build, another
    client's frame): the calling thread renders every tile itself, and the image is the
    one the frame gives on its own."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core")
    rng = np.random.default_rng(3)
    vol = sc.Volume(rng.random((12, 10, 14)).astype(np.float32))
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.3)
    cam = sc.Camera.orbit(vol, 25.0, 15.0)
    expected = sc.render(vol, tf, cam, 40, 24, index="naive").rgba
    helpers = parallel._helpers()
    release = threading.Event()
    blockers = [helpers.submit(release.wait, 30) for _ in range(helpers._max_workers)]
    result = {}
    caller = threading.Thread(target=lambda: result.update(img=sc.render(vol, tf, cam, 40, 24, index="naive")))
    try:
        caller.start()
        caller.join(20)  # the helpers stay blocked all along: a render that waited for them hangs
        assert not caller.is_alive(), "the frame waited for a busy helper pool"
    finally:
        release.set()
        for b in blockers:
            b.result()
    np.testing.assert_array_equal(result["img"].rgba, expected)
