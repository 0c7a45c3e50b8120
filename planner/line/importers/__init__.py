"""Bring your own line: importers from CSV, OSRD railjson and railML 2.x into a schema-v1 line database.

One module per source (:mod:`.csv`, :mod:`.railjson`, :mod:`.railml`) builds
pandas tables of the line database; :mod:`.common` holds what they share: the
TOML of what a source cannot give (``--extra``), the documented defaults and
the summary that lists every default used, and :func:`.common.write_line`,
which writes the tables to a temporary folder, validates it with the project's
validator and only then renames it to the target. A malformed source raises
:class:`planner.errors.SourceError` naming the file, element and field; it
never leaves a folder behind.
"""
from __future__ import annotations

from planner.line.importers.common import ImportSummary, write_line

__all__ = ["ImportSummary", "write_line"]
