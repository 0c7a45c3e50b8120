"""A published run folder as the report reads it: its manifest, its copy of each line database, its datasets.

Takes a run folder (``outputs/r<NNNN>-<digest>/``); gives the manifest (checked
to be a planner run), the run's input copy of a line (``inputs/<line_id>/``,
checked against the manifest's ``source_digest``) and a line's rows of a
dataset as pandas. One-line :class:`planner.errors.InputError` on a folder
that is not a run or whose copy was altered.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Sequence

from planner.errors import InputError

INPUTS_DIR = "inputs"
"""Folder of a run that holds the copy of each line database it planned (``inputs/<line_id>/*.parquet``)."""


def read_manifest(run_dir: Path) -> dict[str, Any]:
    p = Path(run_dir) / "manifest.json"
    if not p.is_file():
        raise InputError(f"{run_dir}: not a published run (no manifest.json); give a folder like outputs/r0007-…")
    try:
        m = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise InputError(f"{p}: unreadable manifest ({e}); the run is damaged, compare another one") from None
    if not isinstance(m, dict) or "run_id" not in m:
        raise InputError(f"{p}: not a planner run manifest (no run_id)")
    return m


def line_inputs(run_dir: Path, manifest: dict[str, Any], line_id: str) -> Path | None:
    """The run's copy of a line database, when present and matching the manifest's ``source_digest``."""
    from planner.line.loader import source_digest

    rec = next((x for x in manifest.get("lines", []) if x.get("line_id") == line_id), None)
    if rec is None:
        return None
    folder = Path(run_dir) / INPUTS_DIR / line_id
    if not folder.is_dir():
        return None
    if source_digest(folder) != rec.get("source_digest"):
        raise InputError(f"{folder}: its tables do not match the run manifest's source_digest; "
                         "the run's input copy was altered, compare another run")
    return folder


def read_line_dataset(run_dir: Path, dataset: str, line_id: str, columns: Sequence[str] | None = None):
    """A dataset of one line as pandas (partition columns as strings), or None when the run has none;
    ``columns``: only these (of a dataset with a ``line`` column or partition, as every dataset of a run has)."""
    import pyarrow.compute as pc

    from planner.io.parquet import read_dataset

    if not (Path(run_dir) / dataset).is_dir():
        return None
    t = read_dataset(run_dir, dataset, columns=None if columns is None else list(dict.fromkeys([*columns, "line"])))
    if "line" in t.column_names:
        t = t.filter(pc.equal(t.column("line"), line_id))
    return (t if columns is None else t.select(list(columns))).to_pandas()


def path_id(line_id: str) -> str:
    """A line id checked for use as a file or partition name (refused otherwise)."""
    from planner.bundle.manifest import check_id

    return check_id(line_id, "line id")
