"""Index build options: unknown or misplaced ones are one clear ParameterError (issue 15 item 7,
issue 14 item 4), never a TypeError from inside an index class."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.index import index_options, parse_index_spec
from sparsecast.index.registry import RENDER_PARAMETERS, SHARED_WITH_INDICES, indices_taking


@pytest.fixture(scope="module")
def small():
    vol = sc.Volume(np.zeros((9, 9, 9), np.float32))
    return vol, sc.TransferFunction.preset("viridis", (0.0, 1.0))


def test_options_come_from_the_index_classes():
    assert index_options("naive") == ()
    assert index_options("grid-pc") == ("cell",) and index_options("grid-mm") == ("cell",)
    assert set(index_options("lbvh")) == {"brick", "prune", "voting"}
    # the hybrids forward **options to the k-d tree
    assert index_options("hybrid-pc") == index_options("kdtree-shallow")
    assert "min_leaf" in index_options("hybrid-mm")
    assert indices_taking("cell") == ["grid-mm", "grid-pc"]


def test_misspelt_option_names_what_the_index_takes(small):
    with pytest.raises(sc.ParameterError) as exc:
        sc.build_index(*small, "grid-pc", cel=8)
    msg = str(exc.value)
    assert "'cel'" in msg and "grid-pc takes options: cell" in msg and "did you mean 'cell'" in msg
    with pytest.raises(sc.ParameterError, match="'brik'.*brick, prune, voting"):
        parse_index_spec("lbvh:brik=4")


def test_cell_on_an_index_without_cells_names_the_grids(small):
    vol, tf = small
    with pytest.raises(sc.ParameterError) as exc:
        sc.render(vol, tf, sc.Camera.orbit(vol), 8, 8, index="naive", cell=7)
    msg = str(exc.value)
    assert "'naive'" in msg and "no build options" in msg and "applies to: grid-mm, grid-pc" in msg


@pytest.mark.parametrize("key, option", [("dt", "--dt"), ("ert", "--ert"), ("width", "--size"),
                                         ("height", "--size"), ("volume", "FILE"), ("tf", "--tf"),
                                         ("index", "--index"), ("background", "--background"),
                                         ("shading", "--shade"), ("camera", "--azimuth")])
def test_render_parameters_are_not_build_options(key, option):
    with pytest.raises(sc.ParameterError) as exc:
        parse_index_spec(f"grid-pc:{key}=1")
    assert f"'{key}' is a render parameter" in str(exc.value) and option in str(exc.value)


def test_render_parameter_table_matches_render_signature():
    params = inspect.signature(sc.render).parameters
    named = {n for n, p in params.items() if p.kind is not p.VAR_KEYWORD}
    assert named == set(RENDER_PARAMETERS) | set(SHARED_WITH_INDICES)
    assert not set(RENDER_PARAMETERS) & set(SHARED_WITH_INDICES)
    # and no index takes an option that render() would swallow (mode: passed on to the BIH)
    for name in sc.available_indices():
        assert not set(index_options(name) or ()) & (named - set(SHARED_WITH_INDICES)), name
