"""The command-line value parsers of sparsecast.cli.parse: values, and one-line errors naming the option."""

from __future__ import annotations

import pytest

import sparsecast as sc
from sparsecast.cli.parse import (
    none_list,
    parse_background,
    parse_dims,
    parse_index_spec,
    parse_numbers,
    parse_pair,
    parse_size,
    parse_spacing,
)


def test_parse_index_spec_options():
    assert parse_index_spec("grid-pc:cell=8") == ("grid-pc", {"cell": 8})
    assert parse_index_spec("lbvh:prune=None,voting=voxels") == ("lbvh", {"prune": None, "voting": "voxels"})
    assert parse_index_spec("lbvh:prune=0.5") == ("lbvh", {"prune": 0.5})
    with pytest.raises(sc.ParameterError, match="key=value"):
        parse_index_spec("lbvh:prune")
    with pytest.raises(sc.ParameterError, match="unknown index"):
        parse_index_spec("octree")


def test_parse_values():
    assert parse_size("640x480") == (640, 480) and parse_size("32") == (32, 32)
    assert parse_pair("0,1.5", "--tf-range") == (0.0, 1.5)
    assert parse_numbers("1,0.5,0", "--background") == (1.0, 0.5, 0.0)
    assert parse_dims("8X4x2") == (8, 4, 2)
    assert parse_spacing("0.5") == 0.5 and parse_spacing("1,2,3") == [1.0, 2.0, 3.0]
    assert parse_background("white") == "white" and parse_background("1,0,0") == [1.0, 0.0, 0.0]
    assert none_list(None) is None and none_list(["None"]) == [] and none_list(["vtk"]) == ["vtk"]


@pytest.mark.parametrize("call, option", [
    (lambda: parse_size("1x2x3"), "--size"),
    (lambda: parse_pair("1", "--tf-range"), "--tf-range"),
    (lambda: parse_numbers("1,red", "--background"), "--background"),
    (lambda: parse_dims("8xAx2"), "--dims"),
    (lambda: parse_spacing("1;2;3"), "--spacing"),
])
def test_parse_errors_name_the_option(call, option):
    with pytest.raises(sc.ParameterError, match=f"^{option}: expected"):
        call()
