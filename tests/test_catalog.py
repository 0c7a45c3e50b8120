"""The analysts' README is generated from the declared schemas and must match them."""
from pathlib import Path

from planner.report.catalog import datasets, readme

ROOT = Path(__file__).resolve().parents[1]


def test_committed_outputs_readme_is_the_generated_one():
    committed = (ROOT / "outputs" / "README.md").read_text()
    assert committed == readme(), "outputs/README.md is stale: run `planner datasets --write outputs/README.md`"


def test_every_column_is_documented_with_a_unit_or_meaning():
    for d in datasets():
        for f in d.schema:
            desc = (f.metadata or {}).get(b"description", b"").decode()
            assert desc.strip(), f"{d.name}.{f.name} has no description"
