"""The ``features`` bench section on tiny cases: records, interleaved runs, exactness (no timing asserted)."""

from __future__ import annotations

import numpy as np
import pytest

from sparsecast.bench import features


def test_features_section_records_every_case_and_variant():
    recs = []
    features.run(["demo-128"], width=12, height=10, repeat=3, warmup=1, record=lambda **kw: recs.append(kw),
                 label_size=32)
    renders = [r for r in recs if r.get("phase") == "render"]
    cases = {(r["case"], r["variant"]) for r in renders}
    assert cases == {("labels", "all"), ("labels", "half"), ("clip", "unclipped"), ("clip", "half-box"),
                     ("clip", "half-plane"),
                     ("iso", "naive")} | {("iso", i) for i in features.ISO_INDICES} \
        | {("shading", "shaded"), ("shading", "unshaded")}
    for r in renders:
        assert len(r["ms_runs"]) == 3 and r["ms_min"] <= r["ms"] <= r["ms_max"]
        assert r["max_abs_diff"] <= 1e-5, r  # every variant is exact against naive
        assert r["speedup"] > 0
    by = {(r["case"], r["variant"]): r for r in renders if r["case"] != "clip"}
    # Hiding the big labels and clipping away half take fewer samples (the point of the case).
    assert by["labels", "half"]["samples"] < by["labels", "all"]["samples"]
    clip = {(r["method"], r["variant"]): r for r in renders if r["case"] == "clip"}
    assert {m for m, _ in clip} == set(features.CLIP_INDICES)  # each index against its own unclipped frame
    for method in features.CLIP_INDICES:
        base = clip[method, "unclipped"]
        assert base["speedup"] == 1.0 and base["sample_ratio"] == 1.0
        for cut in ("half-box", "half-plane"):
            r = clip[method, cut]
            assert r["samples"] < base["samples"]
            assert r["sample_ratio"] == pytest.approx(base["samples"] / r["samples"])
            assert r["speedup"] == pytest.approx(base["ms"] / r["ms"])
    assert all(by["iso", i]["samples"] < by["iso", "naive"]["samples"] for i in features.ISO_INDICES)
    assert {r["variant"] for r in recs if r.get("phase") == "rebuild"} == {"all", "half"}
    # Shading: each index with the benchmark TF, naive with the dense one; both variants
    # take the same samples (shading changes colours, not where samples are taken), and
    # the unshaded row carries shaded / unshaded ms.
    shading = {}
    for r in renders:
        if r["case"] == "shading":
            shading.setdefault((r["tf"], r["method"]), {})[r["variant"]] = r
    assert set(shading) == {("default", i) for i in features.SHADING_INDICES} | {("dense", "naive")}
    for pair in shading.values():
        assert pair["shaded"]["samples"] == pair["unshaded"]["samples"] > 0
        assert pair["shaded"]["speedup"] == 1.0
        assert pair["unshaded"]["speedup"] == pytest.approx(pair["shaded"]["ms"] / pair["unshaded"]["ms"])


def test_label_scene_is_a_segmentation():
    vol, colours = features.label_scene(24, labels=5)
    ids = vol.label_ids()
    assert set(ids.tolist()) <= {0, 1, 2, 3, 4, 5} and 0 in ids and len(colours) == 5
    assert np.count_nonzero(vol.data == 1) >= np.count_nonzero(vol.data == 5)  # 1 is the largest


def test_features_table_prints_each_record():
    from rich.console import Console

    from sparsecast.bench.report import format_features

    rec = dict(section="features", phase="render", dataset="d", case="iso", variant="lbvh", method="lbvh",
               width=8, height=8, ms=2.0, ms_min=1.5, ms_max=3.0, cores_busy=0.9, samples=1234, speedup=4.2,
               sample_ratio=17.25, max_abs_diff=0.0)
    assert format_features([{**rec, "section": "bih"}]) is None
    console = Console(width=200, record=True)
    console.print(format_features([rec]))
    text = console.export_text()
    assert "iso" in text and "4.20" in text and "17.25" in text and "1.5-3.0" in text
