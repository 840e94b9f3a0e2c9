"""sparsecast._util.checks: the value back when it is fine, else one ParameterError naming the
parameter, what it expected and what it got."""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast._util.checks import as_float, as_int, fail, one_of, positive_float, unit_float, vector3
from sparsecast.errors import ParameterError


def test_values_pass_through():
    assert as_int(8, "n") == 8 and as_int(np.int32(3), "n", 0, 9) == 3
    assert as_int(8.0, "n") == 8 and as_int(" 8", "n") == 8
    assert as_float("0.5", "x", 0, 1) == 0.5 and as_float(np.float32(2), "x") == 2.0
    assert positive_float(1e-9, "dt") == 1e-9
    assert unit_float(1, "t") == 1.0
    assert one_of("big", "byte_order", ("little", "big")) == "big"
    np.testing.assert_array_equal(vector3(2, "spacing", positive=True), [2.0, 2.0, 2.0])


@pytest.mark.parametrize("call, message", [
    (lambda: as_int(0, "brick_size", lo=1), "brick_size: expected an integer >= 1, got 0"),
    (lambda: as_int(np.int64(-1), "n", 0, 9), "n: expected an integer in [0, 9], got -1"),
    (lambda: as_int(8.5, "n"), "n: expected an integer, got 8.5"),
    (lambda: as_int(True, "n"), "n: expected an integer, got True"),
    (lambda: as_int("x", "header_offset", lo=0), "header_offset: expected an integer >= 0, got 'x'"),
    (lambda: as_int(70000, "--port", 0, 65535, expected="0..65535"), "--port: expected 0..65535, got 70000"),
    (lambda: as_float(float("nan"), "t", 0, 1), "t: expected a number in [0, 1], got nan"),
    (lambda: as_float(1.0, "a", 0, 1, hi_open=True), "a: expected a number in [0, 1), got 1.0"),
    (lambda: as_float(None, "x", hi=3), "x: expected a number <= 3, got None"),
    (lambda: positive_float(0, "dt"), "dt: expected a positive number, got 0"),
    (lambda: unit_float("high", "threshold"), "threshold: expected a number in [0, 1], got 'high'"),
    (lambda: one_of("xray", "--mode", ("shaded", "depth")), "--mode: expected one of shaded, depth, got 'xray'"),
    (lambda: one_of(["a"], "m", {"a"}), "m: expected one of a, got ['a']"),
    (lambda: vector3("abc", "origin"), "origin: expected 3 numbers (x, y, z), got 'abc'"),
    (lambda: vector3((1, 2), "spacing"), "spacing: expected 3 values (x, y, z), got (2,)"),
    (lambda: vector3((1, 0, 1), "spacing", positive=True), "spacing: expected positive values, got [1.0, 0.0, 1.0]"),
])
def test_errors_name_parameter_expectation_and_value(call, message):
    with pytest.raises(ParameterError) as exc:
        call()
    assert str(exc.value) == message


def test_fail_is_a_parameter_error():
    err = fail("--size", "WIDTHxHEIGHT", "12")
    assert isinstance(err, ParameterError) and str(err) == "--size: expected WIDTHxHEIGHT, got '12'"
