"""The transfer-function JSON format (``sparsecast-tf/1``): one schema, checked field by field.

:meth:`TransferFunction.load <sparsecast.transfer.TransferFunction.load>` and
:meth:`~sparsecast.transfer.TransferFunction.from_dict` read through
:func:`parse_tf_json` and :func:`check_tf_dict`, so every malformed file (a
``value_range`` of 3 numbers, ragged ``points``, 400-digit numbers, ``table_size:
Infinity``, 100 000-deep nesting, a FIFO or ``/dev/zero``) gives one error:
:class:`~sparsecast.errors.TransferFunctionError` naming the field, what it found
and what it expected, or :class:`~sparsecast.errors.FileFormatError` for a file that
is not a small regular file of UTF-8 JSON.

=============== ======================================== =========
field           value                                    required
=============== ======================================== =========
``points``      1 to 65536 rows of 5 finite numbers      yes
                ``(value, r, g, b, a)``
``value_range`` 2 finite numbers ``[lo, hi]``            yes
``table_size``  integer 256..4096                        no (1024)
``unit_distance`` positive number or null                no
``name``        string of at most 200 characters         no
``format``      ``"sparsecast-tf/1"``                    no
=============== ======================================== =========
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from .errors import FileFormatError, TransferFunctionError

__all__ = ["TF_FORMAT", "MAX_TF_BYTES", "parse_tf_json", "check_tf_dict", "read_tf_file"]

TF_FORMAT = "sparsecast-tf/1"
#: bytes a TF file may hold (4096 points of 5 numbers are about 500 kB)
MAX_TF_BYTES = 4 << 20
_MAX_POINTS = 65536
_MAX_NAME = 200
_KNOWN = ("format", "name", "value_range", "table_size", "unit_distance", "points")


def _show(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, float) or math.isfinite(value) else str(value)
    return text if len(text) <= 60 else text[:57] + "..."


def parse_tf_json(data: bytes, source: str) -> Any:
    """The JSON value in ``data``; numbers too long for a float become inf (then rejected
    by :func:`check_tf_dict` with the field's name), deep nesting an error."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{source}: not UTF-8 text ({exc}); expected a JSON transfer function") from None
    try:
        # parse_int=float: a 400-digit (or 5000-digit) integer is a number out of range,
        # not Python's "exceeds the limit for integer string conversion".
        return json.loads(text, parse_int=float, parse_constant=float)
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"{source}: not valid JSON ({exc}); expected a JSON transfer function") from None
    except RecursionError:
        raise FileFormatError(f"{source}: JSON nested too deeply; expected a flat TF object") from None


def _number(value: Any, field: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TransferFunctionError(f"{source}: {field}: expected a number, got {_show(value)}")
    x = float(value)
    if not math.isfinite(x) or abs(x) > 1e300:
        raise TransferFunctionError(f"{source}: {field}: expected a finite number of at most 1e300, got {_show(value)}")
    return x


def check_tf_dict(d: Any, source: str) -> dict[str, Any]:
    """The TF fields of ``d`` as plain Python values, checked against the schema above.

    Returns
    -------
    dict
        ``points`` (list of 5-float lists), ``value_range`` (2-float tuple),
        ``table_size`` (int), ``unit_distance`` (float or None), ``name`` (str).

    Raises
    ------
    TransferFunctionError
        The first field that does not fit, by name.
    """
    if not isinstance(d, dict):
        raise TransferFunctionError(f"{source}: expected a JSON object with 'points' and 'value_range', "
                                    f"got {type(d).__name__}")
    fmt = d.get("format", TF_FORMAT)
    if fmt != TF_FORMAT:
        raise TransferFunctionError(f"{source}: format: expected {TF_FORMAT!r}, got {_show(fmt)}")
    for field in ("points", "value_range"):
        if field not in d:
            raise TransferFunctionError(f"{source}: {field}: missing; expected one of the fields {', '.join(_KNOWN)}")
    points = d["points"]
    if not isinstance(points, list) or not 1 <= len(points) <= _MAX_POINTS:
        raise TransferFunctionError(
            f"{source}: points: expected a list of 1 to {_MAX_POINTS} rows [value, r, g, b, a], got {_show(points)}")
    rows = []
    for i, row in enumerate(points):
        if not isinstance(row, list) or len(row) != 5:
            n = f"{len(row)} values" if isinstance(row, list) else type(row).__name__
            raise TransferFunctionError(
                f"{source}: points[{i}]: expected 5 numbers [value, r, g, b, a], got {n}: {_show(row)}")
        rows.append([_number(x, f"points[{i}][{j}]", source) for j, x in enumerate(row)])
    vr = d["value_range"]
    if not isinstance(vr, list) or len(vr) != 2:
        n = f"{len(vr)} values" if isinstance(vr, list) else type(vr).__name__
        raise TransferFunctionError(f"{source}: value_range: expected 2 numbers [lo, hi], got {n}: {_show(vr)}")
    lo, hi = (_number(x, f"value_range[{j}]", source) for j, x in enumerate(vr))
    size = d.get("table_size", 1024)
    if (isinstance(size, bool) or not isinstance(size, (int, float)) or not math.isfinite(size)
            or size != int(size) or not 256 <= size <= 4096):
        raise TransferFunctionError(f"{source}: table_size: expected an integer 256..4096, got {_show(size)}")
    unit = d.get("unit_distance")
    if unit is not None:
        unit = _number(unit, "unit_distance", source)
        if unit <= 0:
            raise TransferFunctionError(f"{source}: unit_distance: expected a positive number or null, got {_show(unit)}")
    name = d.get("name", "custom")
    if not isinstance(name, str) or len(name) > _MAX_NAME:
        raise TransferFunctionError(f"{source}: name: expected a string of at most {_MAX_NAME} characters, "
                                    f"got {_show(name)}")
    return {"points": rows, "value_range": (lo, hi), "table_size": int(size), "unit_distance": unit, "name": name}


def read_tf_file(path: Path) -> Any:
    """The JSON value of a TF file: a regular file of at most :data:`MAX_TF_BYTES`."""
    from .io.files import read_bounded

    return parse_tf_json(read_bounded(path, MAX_TF_BYTES, "transfer-function JSON file"), str(path))
