"""The isosurface pair test over a packet of samples (`kernels.iso._crossing_in`):
one test for a packet's pairs says what the pair-by-pair test says, ties with the
isovalues and NaN included, so skipping crossing-free packets keeps every hit."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from sparsecast.kernels.iso import _crossing_in
from sparsecast.kernels.packet import PACKET

_crossing = njit(_crossing_in.py_func)


def _pairwise(values, buf, count, f_prev, has_prev):
    seq = ([f_prev] if has_prev else []) + list(buf[:count])
    return any((a >= v) != (b >= v) for v in values for a, b in zip(seq, seq[1:]))


# Few distinct values, so that samples often equal an isovalue or each other.
_value = st.sampled_from([0.0, 1.0, 2.0, 2.5, 3.0, math.nan])


@settings(max_examples=300, deadline=None)
@given(values=st.lists(st.sampled_from([0.5, 1.0, 2.0, 2.5, 3.0]), min_size=1, max_size=3),
       lanes=st.lists(_value, min_size=PACKET, max_size=PACKET), count=st.integers(1, PACKET),
       f_prev=_value, has_prev=st.booleans())
def test_packet_crossing_test_equals_the_pairwise_test(values, lanes, count, f_prev, has_prev):
    v = np.array(values)
    buf = np.array(lanes)
    assert _crossing(v, buf, count, f_prev, has_prev) == _pairwise(values, buf, count, f_prev, has_prev)


def test_a_crossing_in_the_last_counted_pair_is_found_and_one_past_count_is_not():
    v = np.array([1.0])
    buf = np.zeros(PACKET)
    buf[5] = 2.0
    assert _crossing(v, buf, 6, 0.0, True)
    assert not _crossing(v, buf, 5, 0.0, True)
    assert _crossing(v, buf, 5, 2.0, True)  # only the pair (f_prev, buf[0]) crosses
    assert not _crossing(v, buf, 5, 2.0, False)
