"""The ``scale`` bench section on a tiny size: one subprocess per source kind, records with
every field (no timing asserted), and the field generator."""

from __future__ import annotations

import numpy as np

from sparsecast.bench import scale
from sparsecast.bench.report import format_scale

INDICES = ["naive", "grid-pc", "kdtree-deep"]


def test_scale_section_records_every_kind_and_index(tmp_path):
    recs = []
    scale.run(None, width=12, height=10, repeat=3, warmup=1, record=lambda **kw: recs.append(kw),
              sizes=(40,), folder=tmp_path, indices=INDICES, naive_max=32)
    loads = {r["kind"]: r for r in recs if r["phase"] == "load"}
    assert set(loads) == set(scale.KINDS), recs
    for kind, r in loads.items():
        assert r["dataset"] == "nbody-40" and r["size"] == 40
        assert r["storage"] == ("bricked" if kind == "zarr" else "dense") and r["lazy"] == (kind == "zarr")
        for field in ("open_ms", "stats_ms", "first_image_ms", "write_s", "pool_bytes"):
            assert r[field] > 0, (kind, field)
        assert r["dense_bytes"] == 40 ** 3 * (1 if kind.endswith("-u8") else 4) and r["peak_rss"] > 0
        assert r["rss_over_dense"] == r["peak_rss"] / r["dense_bytes"]
        assert 0 < r["occupancy"] < 1 and 0 < r["stored_bricks"] <= r["bricks"]
        assert r["resident_bricks"] <= r["stored_bricks"]
        assert r["first_index"] in INDICES + ["naive"]
    renders = [r for r in recs if r["phase"] == "render"]
    assert {(r["kind"], r["method"]) for r in renders} == {(k, m) for k in scale.KINDS for m in INDICES[1:]}
    for r in renders:
        assert len(r["ms_runs"]) == 3 and r["ms_min"] <= r["ms"] <= r["ms_max"]
        assert r["build_ms"] > 0 and r["rebuild_ms"] > 0 and r["samples"] > 0
    # naive is capped above naive_max, and says so
    skipped = [r for r in recs if r["phase"] == "skipped"]
    assert {(r["kind"], r["method"]) for r in skipped} == {(k, "naive") for k in scale.KINDS}
    assert all("capped at 32^3" in r["reason"] for r in skipped)
    # the same field and TF: every kind of one dtype takes the same samples
    for m in INDICES[1:]:
        for u8 in (False, True):
            assert len({r["samples"] for r in renders if r["method"] == m and r["kind"].endswith("-u8") == u8}) == 1, m
    assert list(tmp_path.iterdir()) == []  # the files are removed
    assert format_scale([{**r, "section": "scale"} for r in recs]).row_count == len(recs)


def test_field_is_the_same_whatever_the_slab_and_background_is_zero():
    whole = np.concatenate([s for _, s in scale.nbody_slabs(48, slab=48)])
    pieces = list(scale.nbody_slabs(48, slab=7))
    assert [z0 for z0, _ in pieces] == list(range(0, 48, 7))
    np.testing.assert_array_equal(np.concatenate([s for _, s in pieces]), whole)
    assert whole.dtype == np.float32 and whole.min() == 0.0 and whole.max() > 1.0
    assert 0.001 < np.count_nonzero(whole) / whole.size < 0.2  # sparse, not empty


def test_written_stores_load_lazily_with_empty_chunks(tmp_path):
    """Chunks of background are written too: a lazy source refuses a store with absent chunks."""
    import sparsecast as sc

    paths = scale.write_field(48, tmp_path, chunk=8)
    vol = sc.load_volume(paths["zarr"], lazy=True)
    dense = np.concatenate([s for _, s in scale.nbody_slabs(48)])
    np.testing.assert_array_equal(vol.to_dense(), dense)
    np.testing.assert_array_equal(sc.load_volume(paths["npy"]).data, dense)
    np.testing.assert_array_equal(sc.load_volume(paths["raw"]).data, dense)
