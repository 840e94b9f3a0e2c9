"""The ``distributed`` bench section on a tiny field: every case recorded, each image equal
to the single process's, and the model rows (no timing asserted)."""

from __future__ import annotations

import pytest

pytest.importorskip("distributed")

from sparsecast.bench import distributed as section  # noqa: E402


def test_distributed_section_records_every_case_and_matches_one_process():
    recs = []
    section.run(None, width=24, height=20, repeat=3, warmup=1, record=lambda **kw: recs.append(kw), edge=40,
                pieces=(1, 2))
    frames = {(r["tf"], r["method"]): r for r in recs if r["phase"] == "frame"}
    assert set(frames) == {(tf, m) for tf in ("sparse", "dense") for m in ("single", "cluster-1", "cluster-2")}
    for name, r in frames.items():
        assert r["max_diff"] <= 1e-5, name
        assert len(r["ms_runs"]) == 3 and r["ms_min"] <= r["ms"] <= r["ms_max"]
        assert len(r["tf_change_runs"]) == 3 and r["samples"] > 0
    for tf in ("sparse", "dense"):
        assert frames[tf, "cluster-2"]["pieces"] == 2 and frames[tf, "cluster-2"]["bytes_moved"] > 0
        assert frames[tf, "single"]["ratio_vs_single"] == 1.0
        assert frames[tf, "cluster-2"]["samples"] == frames[tf, "single"]["samples"] or tf == "sparse"
    # the dense TF sees every sample: more than the sparse one
    assert frames["dense", "single"]["samples"] > frames["sparse", "single"]["samples"]
    assert {r["width"] for r in recs if r["phase"] == "composite"} == {256, 512, 1024}
    models = [r for r in recs if r["phase"] == "model"]
    assert [r["machines"] for r in models] == [1, 2, 4, 8, 16, 32] and all(r["ms"] > 0 for r in models)
