"""``planner robustness JOB.toml [--days N --seed S --day D]``: the day as it will run, and its punctuality."""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Optional

import typer

from . import app
from .checks import DAY_HELP


@app.command()
def robustness(
    job_file: Path = typer.Argument(..., help="Job file: its lines, operating day, [conflicts] and [robustness]."),
    days: Optional[int] = typer.Option(None, "--days", help="Days to simulate (default the job's [robustness] days; "
                                       "0: the predicted day only)."),
    seed: Optional[int] = typer.Option(None, "--seed", help="Seed of the primary delays (default the job's)."),
    day: Optional[str] = typer.Option(None, "--day", help=DAY_HELP),
    out: Optional[Path] = typer.Option(None, "--out", help="Output folder (default <output_root>/robustness): "
                                       "delay_events/, delay_activities/, robustness_*/ datasets and "
                                       "report/<line>_robustness.html."),
    jobs: int = typer.Option(-1, "--jobs", help="Worker processes for the simulated days (-1 = all cores)."),
) -> None:
    """Carry every delay of the operating day forward (a late arrival delays the departure, a train held at a
    block waits), then simulate many days with random primary delays and report punctuality along the line."""
    from planner import load_line
    from planner.datasets.delays import events_frame, write_day
    from planner.errors import InputError
    from planner.job.config import load_job
    import pandas as pd

    from planner.delay.network import ARRIVAL
    from planner.job.robustness import connections, day_as_it_runs, merged_summary
    from planner.network.sections import part_names, plan_sections, restricted, section_line, stream_of
    from planner.network.arrivals import train_curves
    from planner.network.check import check_timetable
    from planner.pages.robustness import write_page
    from planner.io.paths import check_path_id

    from .checks import check_jobs, check_out_dir, day_line
    from .progress import bar as progress_bar

    check_jobs(jobs)
    if days is not None and days < 0:
        raise InputError(f"--days must be ≥ 0, found {days}")
    if seed is not None and seed < 0:
        raise InputError(f"--seed must be ≥ 0, found {seed}")
    job = load_job(job_file)
    dest = out if out is not None else job.resolve(job.job.output_root) / "robustness"
    check_out_dir(dest, "--out", "robustness datasets")
    params = {k: v for k, v in dataclasses.asdict(job.conflicts).items() if k != "enabled"}  # as the night's
    links = connections(job)
    for path in job.job.lines:
        lifted: dict = {}
        line = day_line(load_line(job.resolve(path)), job_file, day, lifted)
        if line.network is None:
            raise InputError(f"{path}: no track network; the day as it runs needs nodes.parquet and edges.parquet")
        # section by section, as the night computes it (planner.network.sections): the same draws, the same files
        sections = plan_sections(line, links)
        files, frames, events, summaries = [], [], [], []
        with progress_bar() as bar:
            t = bar.add_task(f"{line.line_id}: run curves", total=None)
            s = bar.add_task(f"{line.line_id}: simulated days", total=None)
            for sec, part in zip(sections, part_names(len(sections))):
                sl, lift = section_line(line, sec), restricted(lifted, sec)
                check = check_timetable(sl, params, curves=train_curves(sl, lift, n_jobs=jobs),
                                        curve_progress=lambda d, n: bar.update(t, completed=d, total=n))
                pday, stats, summary, held = day_as_it_runs(
                    check, sl, job, days=days, seed=seed, n_jobs=jobs, stream=stream_of(sec, line),
                    progress=lambda d, n: bar.update(s, completed=d, total=n))
                directions = {tr.train_id: tr.direction for tr in check.trains}
                written, fr = write_day(pday, stats, held, sl, directions, dest, part)
                files += written
                frames.append(fr)
                events.append(events_frame(pday, directions))
                summaries.append((summary, int((pday.net.ev_kind == ARRIVAL).sum())))
        summary = {**merged_summary(summaries)}
        frames = None if frames[0] is None else tuple(pd.concat(list(f), ignore_index=True) for f in zip(*frames))
        page = dest / "report" / f"{check_path_id(line.line_id, 'line id ')}_robustness.html"
        summary["day"] = day or job.day.day
        summary["restrictions"] = _in_force(line)
        write_page(page, line.name, summary, *(frames or (None, None, None)), pd.concat(events, ignore_index=True))
        for msg in summary_lines(line.line_id, summary, frames):
            typer.echo(msg)
        typer.echo(f"  wrote {len(files)} datasets under {dest} and {page}")


def summary_lines(line_id: str, s: dict, frames) -> list[str]:
    """What ``planner robustness`` prints per line."""
    out = [f"line {line_id}: {s['trains']} trains, {s['events']} events, {s['activities']} activities"
           + (f" ({s['dropped']} headways left out: they closed a cycle)" if s["dropped"] else ""),
           f"  predicted day: {s['late_trains']} trains late, largest delay {s['max_delay_s']:.1f} s; "
           f"trains held by another: {s['day_conflicts']} pairs ({s['day_conflicts'] - s['knock_on_conflicts']} "
           f"a conflict of the timetable as planned, {s['knock_on_conflicts']} knock-on)"
           + (f" ({', '.join(s['knock_on_places'][:5])}{', …' if len(s['knock_on_places']) > 5 else ''})"
              if s["knock_on_places"] else "")]
    if frames is None:
        out.append("  no days simulated ([robustness] days = 0; --days N simulates N days)")
        return out
    trains, stations, _acts = frames
    arr = trains[trains["event"] == "arrival"]
    share = {m: float(arr[f"within_{m}s"].mean()) for m in (60, 180, 300)}
    knock = float(arr["knock_on_s"].sum() / arr["mean_delay_s"].sum()) if arr["mean_delay_s"].sum() > 0 else 0.0
    out.append(f"  {s['days']} days (seed {s['seed']}): arrivals within 1 / 3 / 5 min: {share[60]:.1%} / "
               f"{share[180]:.1%} / {share[300]:.1%}; mean arrival delay {arr['mean_delay_s'].mean():.1f} s, "
               f"{knock:.0%} of it knock-on")
    for r in s["rules"]:
        out.append(f"    primary delays: {r}")
    return out


def _in_force(line) -> list[str]:
    """The ids of the temporary restrictions of the day's line (those :func:`.checks.day_line` kept in it)."""
    from planner.line.daily import TEMPORARY_KIND

    return sorted({s.restriction_id for s in line.speed_limits if s.kind == TEMPORARY_KIND and s.restriction_id})
