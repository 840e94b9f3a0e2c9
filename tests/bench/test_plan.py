"""The case plan: every key once, in run order, with fewer views where the config says."""

from __future__ import annotations

from sparsecast.bench.plan import CasePlan


def _plan(**kw) -> CasePlan:
    base = dict(datasets=["a"], tfs=["default", "dense"], methods=["naive", "grid-pc"], peers=["vtk"],
                sections=["irt"], sizes=[(16, 16), (8, 8)], views=[(30.0, 20.0), (0.0, 0.0), (90.0, 45.0)],
                dense_views=1, peer_views=2)
    return CasePlan(**{**base, **kw})


def test_keys_are_unique_and_counted_per_case():
    plan = _plan()
    keys = plan.keys()
    assert len({tuple(sorted(k.items())) for k in keys}) == len(keys)
    # load + brick_stats; per TF: classify + per method (2 builds + sizes x views) + peer sizes x views
    default = 1 + 2 * (2 + 2 * 3) + 2 * 2
    dense = 1 + 2 * (2 + 2 * 1) + 2 * 1
    assert len(keys) == 2 + default + dense + 1
    assert keys[0] == {"dataset": "a", "phase": "load"}
    assert keys[-1] == {"method": "irt", "phase": "section_done"}


def test_render_keys_name_the_view():
    keys = _plan(sizes=[(12, 8)]).render_keys("a", "default", "naive")
    assert keys[0] == {"dataset": "a", "tf": "default", "method": "naive", "width": 12, "height": 8,
                       "view": "az30_el20", "phase": "render"}
    assert [k["view"] for k in _plan().render_keys("a", "dense", "vtk", peer=True)] == ["az30_el20"] * 2
