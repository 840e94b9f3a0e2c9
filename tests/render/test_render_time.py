"""Bounded render time: a cap on samples per image, and frames that stop between chunks."""

from __future__ import annotations

import _thread
import signal
import time

import numpy as np
import pytest

import sparsecast as sc
from sparsecast import ParameterError
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
