"""The benchmark catalogue (sparsecast.bench.catalog) and the shared data folder it reads from."""

from __future__ import annotations

from sparsecast.bench import DATASETS, find_shared_data


def test_find_shared_data_honours_env(monkeypatch, tmp_path):
    monkeypatch.setenv("SPARSECAST_DATA", str(tmp_path))
    assert find_shared_data() == tmp_path.resolve()


def test_registry_demo_is_always_available():
    assert DATASETS["demo"].available()
    assert "mni152" in DATASETS


def test_shared_dataset_skips_cleanly_without_data(monkeypatch, tmp_path):
    monkeypatch.setenv("SPARSECAST_DATA", str(tmp_path))  # an empty folder
    assert not DATASETS["mni152"].available()


def test_sweep_cases_are_generated():
    case = DATASETS["fig5b-256-k0008"]
    assert case.file is None and not case.default and case.available()
