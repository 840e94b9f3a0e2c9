"""Idle OpenMP threads sleep: sparsecast sets a passive wait policy unless the user chose one.
``run_chunks`` covers every item once, on several threads, and never waits on a busy pool."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import numba
import numpy as np
import pytest
from numba import njit

from sparsecast.kernels import parallel
from sparsecast.kernels.parallel import run_chunks


def _policy_after_import(env_policy: str | None) -> str:
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    if env_policy is not None:
        env["OMP_WAIT_POLICY"] = env_policy
    code = "import os, sparsecast; print(os.environ.get('OMP_WAIT_POLICY'))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return out.stdout.strip()


def test_import_makes_idle_threads_passive():
    assert _policy_after_import(None) == "PASSIVE"


def test_a_policy_the_user_set_is_kept():
    assert _policy_after_import("ACTIVE") == "ACTIVE"


@njit(nogil=True)
def _mark(first, last, hits, owner, me):
    for i in range(first, last):
        hits[i] += 1
        owner[i] = me[0]


def _pieces(n, grain, threads):
    hits = np.zeros(n, np.int64)
    calls = []

    def kernel(first, last, hits):
        calls.append((first, last, threading.get_ident()))
        _mark(first, last, hits, np.zeros(n, np.int64), np.zeros(1, np.int64))

    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        run_chunks(kernel, n, grain, hits)
    finally:
        numba.set_num_threads(before)
    return hits, sorted(calls)


@pytest.mark.parametrize("n, grain", [(0, 4), (1, 4), (7, 3), (64, 8), (65, 8), (1000, 1)])
@pytest.mark.parametrize("threads", [1, 2])
def test_every_item_is_taken_once(n, grain, threads):
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip("one core")
    hits, calls = _pieces(n, grain, threads)
    assert (hits == 1).all()
    if threads == 1 or n <= grain:  # one piece: one call, on the caller's thread
        assert [c[:2] for c in calls] == [(0, n)]
    else:  # pieces of `grain` items, disjoint and in order when sorted
        assert [c[:2] for c in calls] == [(i, min(n, i + grain)) for i in range(0, n, grain)]


def test_pieces_run_on_more_than_one_thread():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core")
    seen = set()
    gate = threading.Barrier(2, timeout=10)

    def kernel(first, last):
        seen.add(threading.get_ident())
        if first < 2:  # the first two pieces meet: each is on its own thread
            gate.wait()

    before = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        run_chunks(kernel, 4, 1)
    finally:
        numba.set_num_threads(before)
    assert len(seen) == 2


def test_a_busy_pool_does_not_block_the_caller():
    """Helpers still running another caller's work: the caller takes every piece itself."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core")
    release = threading.Event()
    blockers = [parallel._helpers().submit(release.wait, 30) for _ in range(parallel._helpers()._max_workers)]
    result = {}
    caller = threading.Thread(target=lambda: result.update(done=_pieces(40, 4, 2)))
    try:
        caller.start()
        caller.join(20)  # the helpers stay blocked all along: a caller that waited for them hangs
        assert not caller.is_alive(), "run_chunks waited for a busy pool"
        hits, calls = result["done"]
        assert (hits == 1).all()
        assert {c[2] for c in calls} == {caller.ident}
    finally:
        release.set()
        for b in blockers:
            b.result()


def test_a_kernel_error_reaches_the_caller():
    def kernel(first, last):
        if first == 8:
            raise ValueError("piece 8")

    before = numba.get_num_threads()
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    try:
        with pytest.raises(ValueError, match="piece 8"):
            run_chunks(kernel, 16, 4)
    finally:
        numba.set_num_threads(before)


def test_an_interrupted_caller_stops_the_helpers():
    """Ctrl-C in the caller's piece: the helpers finish the piece they are in and take no more."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core")
    import time

    caller = threading.get_ident()
    helper_pieces = []

    def kernel(first, last):
        if threading.get_ident() == caller:
            raise KeyboardInterrupt
        helper_pieces.append(first)
        time.sleep(0.005)  # (releases the GIL, as a nogil kernel does)

    before = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        with pytest.raises(KeyboardInterrupt):
            run_chunks(kernel, 200, 1)
    finally:
        numba.set_num_threads(before)
    assert len(helper_pieces) < 20  # without the stop, the helper takes all the other 199
