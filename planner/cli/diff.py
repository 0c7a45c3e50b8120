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
            write_bytes_atomic(page, diff_page(ch, run_a, run_b, out).encode())
            typer.echo(f"  wrote {page}")


def diff_page(ch, run_a: Path, run_b: Path, out: Path) -> str:
    """The page ``planner diff --out`` writes for one line: a title naming the line and both runs, links to
    each run's overview (relative to the page, so the folders can move together), then the changes."""
    import html
    import os

    from planner.pages.changes import changes_html

    e = lambda x: html.escape(str(x), quote=True)  # noqa: E731
    link = lambda run, rid: (f"<a href='{e(os.path.relpath(Path(run) / 'index.html', out))}'>"  # noqa: E731
                             f"{e(rid)}</a>")
    title = f"Line {ch.line_id}: run {ch.run} against run {ch.base_run}"
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>{e(title)}</title></head><body style='font-family:system-ui;max-width:1200px;margin:auto;"
            f"padding:0 12px'><h1 style='font-size:22px'>{e(title)}</h1>"
            f"<p>Overviews: {link(run_a, ch.base_run)} (before) · {link(run_b, ch.run)} (after)</p>"
            + changes_html(ch, title="What changed") + "</body></html>\n")
