"""Parameter checks in one place: small typed helpers that return the checked value or
raise :class:`~sparsecast.errors.ParameterError`.

Every message has one shape, ``"NAME: expected WHAT, got VALUE"``: the parameter (as
the caller knows it: ``brick_size``, ``--port``), what it must be, and what was
passed, so the command line can print it as one line that needs no traceback.
``expected=`` replaces the generated WHAT where a caller says it better (``"0..65535
(0 picks a free port)"``).

>>> as_int(8, "brick_size", lo=1)
8
>>> as_int(0, "brick_size", lo=1)
Traceback (most recent call last):
...
sparsecast.errors.ParameterError: brick_size: expected an integer >= 1, got 0
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Collection
from typing import Any, TypeVar

import numpy as np

from ..errors import ParameterError

__all__ = ["fail", "as_int", "as_float", "positive_float", "unit_float", "one_of", "vector3"]

T = TypeVar("T")


def fail(name: str, expected: str, found: Any) -> ParameterError:
    """The error ``"NAME: expected EXPECTED, got FOUND"`` (to ``raise``).

    Numbers are shown as they print (``5``, not NumPy's ``np.int64(5)``), everything
    else by its repr (strings in quotes, so an empty or blank one shows).
    """
    shown = str(found) if isinstance(found, (numbers.Number, np.generic)) else repr(found)
    return ParameterError(f"{name}: expected {expected}, got {shown}")


def _bounds(kind: str, lo, hi, lo_open: bool = False, hi_open: bool = False) -> str:
    """``"an integer >= 1"``, ``"a number in (0, 1]"``...: the WHAT of a range check."""
    if lo is not None and hi is not None:
        return f"{kind} in {'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{kind} {'>' if lo_open else '>='} {lo}"
    if hi is not None:
        return f"{kind} {'<' if hi_open else '<='} {hi}"
    return kind


def as_int(value: Any, name: str, lo: int | None = None, hi: int | None = None, *,
           expected: str | None = None) -> int:
    """``value`` as an int in ``[lo, hi]`` (either bound may be None).

    Accepts Python and NumPy integers, integral floats (``8.0``) and integer strings
    (``"8"``); rejects booleans, fractions and anything else.

    Parameters
    ----------
    value : object
        What the caller passed.
    name : str
        The parameter, for the message.
    lo, hi : int, optional
        Inclusive bounds.
    expected : str, optional
        The message's WHAT (default e.g. ``"an integer >= 1"``).

    Returns
    -------
    int

    Raises
    ------
    ParameterError
        Not an integer, or out of range.
    """
    what = expected or _bounds("an integer", lo, hi)
    if isinstance(value, (bool, np.bool_)):
        raise fail(name, what, value)
    if isinstance(value, numbers.Integral):
        n = int(value)
    elif isinstance(value, numbers.Real) and math.isfinite(value) and float(value).is_integer():
        n = int(value)
    elif isinstance(value, str):
        try:
            n = int(value.strip())
        except ValueError:
            raise fail(name, what, value) from None
    else:
        raise fail(name, what, value)
    if (lo is not None and n < lo) or (hi is not None and n > hi):
        raise fail(name, what, value)
    return n


def as_float(value: Any, name: str, lo: float | None = None, hi: float | None = None, *,
             lo_open: bool = False, hi_open: bool = False, expected: str | None = None) -> float:
    """``value`` as a finite float within the bounds (open or closed; either may be None).

    Parameters
    ----------
    value : object
        Anything ``float()`` takes (a number, a NumPy scalar, a numeric string).
    name : str
        The parameter, for the message.
    lo, hi : float, optional
        Bounds; closed unless ``lo_open`` / ``hi_open``.
    expected : str, optional
        The message's WHAT (default e.g. ``"a number in [0, 1]"``).

    Returns
    -------
    float

    Raises
    ------
    ParameterError
        Not a number, NaN or infinite, or out of range.
    """
    what = expected or _bounds("a number", lo, hi, lo_open, hi_open)
    if isinstance(value, (bool, np.bool_)):
        raise fail(name, what, value)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise fail(name, what, value) from None
    if not math.isfinite(x):
        raise fail(name, what, value)
    if lo is not None and (x <= lo if lo_open else x < lo):
        raise fail(name, what, value)
    if hi is not None and (x >= hi if hi_open else x > hi):
        raise fail(name, what, value)
    return x


def positive_float(value: Any, name: str, *, expected: str = "a positive number") -> float:
    """``value`` as a finite float > 0."""
    return as_float(value, name, lo=0.0, lo_open=True, expected=expected)


def unit_float(value: Any, name: str) -> float:
    """``value`` as a float in [0, 1] (an opacity, a threshold fraction)."""
    return as_float(value, name, 0.0, 1.0, expected="a number in [0, 1]")


def one_of(value: T, name: str, choices: Collection[T], *, expected: str | None = None) -> T:
    """``value`` itself if it is one of ``choices``.

    Parameters
    ----------
    value : object
    name : str
        The parameter, for the message.
    choices : collection
        The allowed values (their order is the message's).
    expected : str, optional
        The message's WHAT (default ``"one of a, b, c"``).

    Raises
    ------
    ParameterError
        ``value`` is not among ``choices`` (also when it cannot be compared to them).
    """
    try:
        ok = value in choices
    except TypeError:  # e.g. an unhashable value against a set or dict
        ok = False
    if not ok:
        raise fail(name, expected or "one of " + ", ".join(map(str, choices)), value)
    return value


def vector3(value: Any, name: str, *, positive: bool = False) -> np.ndarray:
    """``value`` (one number, or three for ``(x, y, z)``) as a finite float64 array of shape (3,).

    Parameters
    ----------
    value : float or sequence of 3 floats
        One number stands for all three axes.
    name : str
        The parameter, for the message.
    positive : bool
        Also require every component > 0 (a spacing).

    Raises
    ------
    ParameterError
        Not numbers, not 1 or 3 of them, NaN/Inf, or (``positive``) a component <= 0.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise fail(name, "3 numbers (x, y, z)", value) from None
    if arr.ndim == 0:
        arr = np.repeat(arr, 3)
    if arr.shape != (3,):
        raise ParameterError(f"{name}: expected 3 values (x, y, z), got {np.shape(value)}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name}: expected finite values, got {arr.tolist()}")
    if positive and np.any(arr <= 0):
        raise ParameterError(f"{name}: expected positive values, got {arr.tolist()}")
    return arr
