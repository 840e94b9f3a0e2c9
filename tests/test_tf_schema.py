"""Malformed TF JSON (issue 14, items 2 and 6): one error in the family, naming the field."""

from __future__ import annotations

import json
import os

import pytest

from sparsecast.errors import FileFormatError, TransferFunctionError
from sparsecast.transfer import TransferFunction

GOOD = {"format": "sparsecast-tf/1", "name": "t", "value_range": [0, 1], "table_size": 256,
        "unit_distance": None, "points": [[0, 0, 0, 0, 0], [1, 1, 1, 1, 1]]}


def _load(tmp_path, text):
    p = tmp_path / "tf.json"
    p.write_text(text)
    return TransferFunction.load(p)


@pytest.mark.parametrize("change, field", [
    ({"value_range": [0, 1, 2]}, r"value_range: expected 2 numbers \[lo, hi\], got 3 values"),
    ({"points": [[0, 0, 0, 0, 0], [1, 1, 1, 1]]}, r"points\[1\]: expected 5 numbers.*got 4 values"),
    ({"points": [[0, 0, 0, 0, 0], "x"]}, r"points\[1\]: expected 5 numbers"),
    ({"points": []}, "points: expected a list of 1 to"),
    ({"table_size": "big"}, "table_size: expected an integer 256..4096"),
    ({"table_size": 1e9}, "table_size: expected an integer 256..4096"),
    ({"unit_distance": -1}, "unit_distance: expected a positive number"),
    ({"name": ["x"]}, "name: expected a string"),
    ({"format": "other/2"}, "format: expected 'sparsecast-tf/1'"),
    ({"value_range": [1, 0]}, "value_range: expected finite lo <= hi"),
    ({"points": [[0, 0, 0, 0, 2]]}, "r, g, b, a must lie in"),
])
def test_bad_fields_are_named(tmp_path, change, field):
    with pytest.raises(TransferFunctionError, match=field):
        _load(tmp_path, json.dumps({**GOOD, **change}))


def test_numbers_out_of_range(tmp_path):
    text = json.dumps(GOOD).replace('"value_range": [0, 1]', '"value_range": [0, 1' + "0" * 400 + "]")
    with pytest.raises(TransferFunctionError, match=r"value_range\[1\]: expected a finite number"):
        _load(tmp_path, text)
    text = json.dumps(GOOD).replace('"value_range": [0, 1]', '"value_range": [0, 1' + "0" * 5000 + "]")
    with pytest.raises(TransferFunctionError, match=r"value_range\[1\]"):
        _load(tmp_path, text)
    with pytest.raises(TransferFunctionError, match="table_size: expected an integer 256..4096, got inf"):
        _load(tmp_path, json.dumps(GOOD).replace('"table_size": 256', '"table_size": Infinity'))
    with pytest.raises(TransferFunctionError, match=r"points\[0\]\[1\]"):
        _load(tmp_path, json.dumps(GOOD).replace("[[0, 0", "[[0, NaN"))


def test_deep_nesting_is_one_error(tmp_path):
    with pytest.raises(FileFormatError, match="nested too deeply"):
        _load(tmp_path, '{"points": ' + "[" * 100_000 + "]" * 100_000 + "}")


def test_not_json_or_not_an_object(tmp_path):
    with pytest.raises(FileFormatError, match="not valid JSON"):
        _load(tmp_path, "{")
    with pytest.raises(TransferFunctionError, match="expected a JSON object"):
        _load(tmp_path, "[1, 2]")
    (tmp_path / "u.json").write_bytes(b'{"name": "\xff"}')
    with pytest.raises(FileFormatError, match="not UTF-8"):
        TransferFunction.load(tmp_path / "u.json")


def test_not_regular_or_too_large(tmp_path):
    os.symlink("/dev/zero", tmp_path / "z.json")
    with pytest.raises(FileFormatError, match="character device"):
        TransferFunction.load(tmp_path / "z.json")
    os.mkfifo(tmp_path / "f.json")
    with pytest.raises(FileFormatError, match="FIFO"):
        TransferFunction.load(tmp_path / "f.json")
    (tmp_path / "big.json").write_bytes(b" " * (5 << 20))
    with pytest.raises(FileFormatError, match="larger than"):
        TransferFunction.load(tmp_path / "big.json")


def test_good_file_round_trips(tmp_path):
    tf = _load(tmp_path, json.dumps(GOOD))
    assert tf.table_size == 256 and tf.value_range == (0.0, 1.0)
    assert TransferFunction.load(tf.save(tmp_path / "again.json")).to_dict() == tf.to_dict()
