"""``planner graph LINE --out DIR``: the train graph (time-distance diagram) as SVG/PNG charts and an interactive page."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from . import app
from .checks import DAY_HELP, JOB_HELP


@app.command()
def graph(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    out: Path = typer.Option(..., "--out", help="Output folder for <line>_graph.html and the charts."),
    t_from: Optional[str] = typer.Option(None, "--from", help="Start of the time window HH:MM (default: first departure)."),
    t_to: Optional[str] = typer.Option(None, "--to", help="End of the time window HH:MM (default: last arrival)."),
    train: Optional[str] = typer.Option(None, "--train", help="Train to highlight, with its blocking-time stairway "
                                        "(its id in any case); the page opens on its run."),
    run: Optional[Path] = typer.Option(None, "--run", help="A published run (e.g. outputs/latest) of this line database: "
                                       "its occupation, conflicts, margin_totals and delay_events datasets are used."),
    fmt: str = typer.Option("svg", "--format", help="Chart format: svg or png."),
    job: Optional[Path] = typer.Option(None, "--job", help=JOB_HELP),
    day: Optional[str] = typer.Option(None, "--day", help=DAY_HELP),
) -> None:
    """Draw every train from its predicted run: charts per direction and both, and a page to zoom and hover."""
    from .. import load_line
    from planner.report.published_run import read_line_dataset, path_id, read_manifest
    from ..errors import InputError
    from planner.report.graph_predicted import PREDICTED_COLUMNS
    from planner.report.train_graph import WINDOW_COLUMNS, graph_data, match_train, parse_hhmm, train_graph_chart
    from planner.pages.run_head import run_words
    from planner.pages.train_graph import write_page

    from .checks import check_out_dir, day_line

    if fmt not in ("svg", "png"):
        raise InputError(f"--format must be svg or png, not {fmt!r}")
    check_out_dir(out, "--out", "train graph")
    t0 = parse_hhmm(t_from, "--from") if t_from else None
    t1 = parse_hhmm(t_to, "--to") if t_to else None
    line = day_line(load_line(line_dir), job, day)
    if train and match_train([t.train_id for t in line.trains], train) is None:  # before the run curves are simulated
        raise InputError(f"--train {train}: no such train on line {line.line_id} "
                         f"(e.g. {', '.join(t.train_id for t in line.trains[:3])})")
    kw, label = {}, ""
    if run is not None:
        m = read_manifest(run)
        label = run_words(m.get("run_id"), m.get("operating_day"), m.get("run_date"))
        rec = next((x for x in m.get("lines", []) if x.get("line_id") == line.line_id), None)
        if rec is None or rec.get("source_digest") != line.source_digest:
            raise InputError(f"--run {run}: this run did not plan {line_dir} as it is now (line {line.line_id}, "
                             "source digest differs); run the job again or leave --run out")
        kw = {name: read_line_dataset(run, ds, line.line_id, columns=cols) for name, ds, cols in
              (("windows", "occupation", WINDOW_COLUMNS), ("conflicts", "conflicts", None),
               ("margin_totals", "margin_totals", None), ("delay_events", "delay_events", PREDICTED_COLUMNS))}
    data = graph_data(line, **kw)
    name = path_id(line.line_id)  # becomes a file name: checked again here
    files = [write_page(data, out / f"{name}_graph.html", t0=t0, t1=t1, train=train, run_label=label)]
    for d in ("both", "down", "up"):
        files.append(train_graph_chart(data, out / f"{name}_{d}.{fmt}", direction=d, t0=t0, t1=t1, train=train,
                                       run_label=label))
    nc = int(data.conflicts.conflict_id.nunique()) if data.conflicts is not None and len(data.conflicts) else 0
    typer.echo(f"line {line.line_id}: {len(data.trains)} trains, {nc} conflicts")
    for n in data.notes:
        typer.echo(f"  note: {n}")
    for f in files:
        typer.echo(f"  wrote {f}")
