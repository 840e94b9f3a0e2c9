"""``index="auto"`` (the default): naive when nothing is empty, a skipping index
otherwise, a rebuild-cheap one while the TF is edited; always naive's image."""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.index.auto import EDITING_INDEX, SPARSE_INDEX, choose_index
from synthetic import sparse_volume
from cli_runner import run_cli


@pytest.fixture(scope="module")
def vol():
    return sparse_volume(np.random.default_rng(21), (40, 36, 44), 4)


DENSE = sc.TransferFunction([(0.0, 0.2, 0.4, 0.9, 0.05), (1.0, 1, 1, 1, 0.3)])  # nothing transparent
SPARSE = sc.TransferFunction([(0.0, 1, 1, 1, 0.0), (1.0, 1, 0.5, 0.2, 0.8)])  # zero background empty


def test_dense_tf_picks_naive(vol):
    name, why = choose_index(vol, DENSE)
    assert name == "naive" and why["occupancy"] == 1.0 and "nothing to skip" in why["reason"]
    assert choose_index(vol, DENSE, editing=True)[0] == "naive"


def test_sparse_tf_picks_a_skipping_index(vol):
    name, why = choose_index(vol, SPARSE)
    assert name == SPARSE_INDEX and 0 < why["occupancy"] < 0.9 and not why["editing"]
    name, why = choose_index(vol, SPARSE, editing=True)
    assert name == EDITING_INDEX and why["editing"]


@pytest.mark.parametrize("tf, expected", [(DENSE, "naive"), (SPARSE, SPARSE_INDEX)])
def test_render_default_is_auto_and_equals_naive(vol, tf, expected):
    cam = sc.Camera.orbit(vol, 30, 20)
    img = sc.render(vol, tf, cam, 32, 28, ert=1.0)
    ref = sc.render(vol, tf, cam, 32, 28, ert=1.0, index="naive")
    assert img.stats["index"] == expected and img.stats["auto"]["reason"]
    assert "auto" not in ref.stats
    assert np.abs(img.rgba - ref.rgba).max() <= 1e-5
    assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"]
    if expected != "naive":
        assert img.stats["samples"] < ref.stats["samples"]


def test_build_index_auto_keeps_the_choice(vol):
    idx = sc.build_index(vol, SPARSE, "auto")
    assert idx.name == SPARSE_INDEX and idx.auto["occupancy"] < 0.9
    img = sc.render(vol, SPARSE, sc.Camera.orbit(vol), 16, 16, index=idx)
    assert img.stats["auto"] == idx.auto
    with pytest.raises(sc.ParameterError, match="need a named index"):
        sc.build_index(vol, SPARSE, "auto", cell=8)


def test_cli_reports_the_choice(monkeypatch, capsys, tmp_path):
    code, out, err = run_cli(monkeypatch, capsys, "render", "--size", "16x16", "-o", str(tmp_path / "a.png"))
    assert code == 0, err
    flat = " ".join(out.split())
    assert f"index {SPARSE_INDEX} (auto: " in flat and "non-empty" in flat
