"""The README stands alone: its TF example loads, its suite durations are the suites', its
links stay inside the repository."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

import sparsecast as sc
from sparsecast.bench.suites import SUITES

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _block_after(marker: str) -> str:
    """The fenced code block right after ``<!-- marker -->``."""
    m = re.search(rf"<!-- {marker} -->\s*```\w*\n(.*?)```", README, re.S)
    assert m, f"README has no code block after <!-- {marker} -->"
    return m.group(1)


def test_tf_example_loads_and_means_what_the_text_says(tmp_path):
    text = _block_after("tf-example")
    path = tmp_path / "example.json"
    path.write_text(text)
    tf = sc.TransferFunction.load(path)
    d = json.loads(text)
    assert tf.value_range == tuple(float(v) for v in d["value_range"])
    assert tf.table_size == d["table_size"] and tf.name == d["name"] and tf.unit_distance is None
    np.testing.assert_array_equal(tf.points, np.array(d["points"], float))
    # Transparent up to the second point, opaque-ish above: the example has empty space.
    assert tf.is_empty(0.0, 59.0) and not tf.is_empty(100.0, 120.0)
    assert sc.TransferFunction.from_dict(tf.to_dict()).points.tolist() == tf.points.tolist()


def test_tf_table_lists_every_schema_field():
    from sparsecast import tf_schema

    table = README[README.index("<!-- tf-example -->"):]
    for field in ("points", "value_range", "table_size", "unit_distance", "name", "format"):
        assert f"| `{field}` |" in table
    assert tf_schema.TF_FORMAT in README


def test_suite_table_matches_the_suites():
    rows = re.findall(r"^\| `(\w+)` \| .*? \| ([^|]+?) \|$", README[README.index("<!-- suites -->"):], re.M)
    durations = {name: d for name, d in rows}
    assert set(durations) == set(SUITES)
    for name, suite in SUITES.items():
        assert durations[name] == (suite.duration or "not measured"), name


def test_links_stay_in_the_repository():
    for doc in [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = doc.read_text()
        for target in re.findall(r"\]\(([^)#]+)\)", text):
            if target.startswith(("http://", "https://", "mailto:")):
                continue
            resolved = (doc.parent / target).resolve()
            assert resolved.is_relative_to(ROOT) and resolved.exists(), f"{doc.name}: link {target}"
        assert "../shared" not in text.replace("`../shared/data`", ""), f"{doc.name} names a file outside the repository"
