"""Shading kernels: the specular power by squaring agrees with ``pow``."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from sparsecast.kernels.shade import _power


@njit
def _powers(x, s):
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = _power(x[i], s)
    return out


@pytest.mark.parametrize("s", [0.0, 1.0, 2.0, 3.0, 24.0, 127.0, 1024.0, 0.5, 24.5, 1025.0, 3.0e9])
def test_power_equals_pow(s):
    x = np.concatenate([np.random.default_rng(0).uniform(0.0, 1.0, 2000), [0.0, 1.0, 1e-300, 0.999999]])
    got = _powers(x, s)
    want = x ** s
    # squaring doubles the relative error it is given: at most about s ulps
    eps = np.finfo(float).eps
    np.testing.assert_allclose(got, want, rtol=eps * (2.0 + 2.0 * min(s, 1024.0)), atol=1e-300)
    assert got[-3] == 1.0 ** s and got[-4] == 0.0 ** s
