"""The perf map names the functions compiled in this process at their addresses."""

from __future__ import annotations

import weakref

import numpy as np
import pytest
from numba import njit

pytest.importorskip("elftools")

from sparsecast.bench.perfmap import jit_symbols, write_perf_map  # noqa: E402


class _Target:
    pass


@njit
def _helper(a, i):
    return a[i] * 2.0 + 1.0


@njit
def _kernel(a):
    s = 0.0
    for i in range(a.shape[0]):
        s += _helper(a, i)
    return s


def test_map_names_compiled_functions_at_their_entry_points(tmp_path):
    assert _kernel(np.arange(4.0)) == 2.0 * 6.0 + 4.0
    cres = _kernel.overloads[_kernel.signatures[0]]
    name = cres.fndesc.llvm_func_name
    entry = cres.library.get_pointer_to_function(name)
    # a dead weak proxy among the objects scanned (isinstance on one raises ReferenceError)
    target = _Target()
    dead = weakref.proxy(target)
    del target
    path = write_perf_map(tmp_path / "perf-test.map")
    assert dead is not None
    rows = [line.split(" ", 2) for line in path.read_text().splitlines()]
    assert all(len(r) == 3 for r in rows)
    found = {r[2]: (int(r[0], 16), int(r[1], 16)) for r in rows}
    assert name in found, "the kernel is not in the map"
    address, size = found[name]
    assert address == entry and size > 0
    # the callee Numba linked into the kernel's library is named too (no dispatcher exports it there)
    helper = _helper.overloads[_helper.signatures[0]].fndesc.llvm_func_name
    assert any(n == helper for n in found)
    # sorted, and no two functions overlap
    symbols = jit_symbols()
    assert symbols == sorted(symbols)
    assert all(a + n <= b for (a, n, _), (b, _, _) in zip(symbols, symbols[1:]))
    # the runtime's reference counting, which kernels call at its own address
    from numba.core.runtime import rtsys
    incref = rtsys._library.get_pointer_to_function("NRT_incref")
    assert (incref, "NRT_incref") in {(a, n) for a, _, n in symbols}
