"""``planner diff RUN_A RUN_B``: what changed from one run to another (inputs, legs, flags, conflicts, bundles)."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from . import app


@app.command()
def diff(
    run_a: Path = typer.Argument(..., help="The earlier run folder, e.g. outputs/r0006-…"),
    run_b: Path = typer.Argument(..., help="The later run folder, e.g. outputs/latest."),
    threshold_s: float = typer.Option(0.5, "--threshold-s", help="List legs whose minimum or margin moved by more than this [s]."),
    out: Optional[Path] = typer.Option(None, "--out", help="Also write the changes dataset and an HTML page here."),
) -> None:
    """Compare two runs line by line: changed inputs, and legs, flags, conflicts and bundles they changed."""
    from planner.io.atomic import write_bytes_atomic
    from planner.report.changes import compare_runs, write_changes
    from planner.pages.changes import changes_html
    from .checks import check_out_dir

    check_out_dir(out, "--out", "changes dataset and page")
    result = compare_runs(run_a, run_b, threshold_s=threshold_s)
    for ch in result:
        for msg in ch.summary_lines():
            typer.echo(msg)
        if out is not None:
            for f in write_changes(ch, out):
                typer.echo(f"  wrote {f}")
            page = out / f"{ch.line_id}_changes.html"
            write_bytes_atomic(page, ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>Changes "
                                      f"{ch.base_run} → {ch.run}</title></head><body style='font-family:system-ui;"
                                      "max-width:1200px;margin:auto'>" + changes_html(ch) + "</body></html>\n").encode())
            typer.echo(f"  wrote {page}")
