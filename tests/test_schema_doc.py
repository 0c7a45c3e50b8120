"""The line-database contract ships with the code: docs/line-database.md is generated from planner/line/schema.py."""
from pathlib import Path

from typer.testing import CliRunner

from planner.cli import app
from planner.line.schema import TABLES
from planner.line.schema_doc import DOC_PATH, line_database_doc

ROOT = Path(__file__).resolve().parents[1]


def test_committed_doc_is_the_generated_one():
    committed = (ROOT / DOC_PATH).read_text(encoding="utf-8")
    assert committed == line_database_doc(), "docs/line-database.md is stale: run " \
                                             "`planner schema --write docs/line-database.md`"


def test_every_declared_column_appears_with_its_type():
    doc = line_database_doc()
    for spec in TABLES.values():
        assert f"`{spec.file}`" in doc
        for f in spec.schema:
            assert f"| `{f.name}` | {f.type} |" in doc, (spec.name, f.name)


def test_planner_schema_prints_it_and_validate_points_there(tmp_path):
    r = CliRunner().invoke(app, ["schema"])
    assert r.exit_code == 0 and r.output == line_database_doc()
    (tmp_path / "empty").mkdir()
    r = CliRunner().invoke(app, ["validate", str(tmp_path / "empty")])
    assert r.exit_code == 1 and "docs/line-database.md" in r.output
