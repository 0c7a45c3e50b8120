"""`planner cache verify|clear TARGET`: check or empty the nightly job's work cache.

TARGET is a job file (its ``[job] output_root`` is used) or an output root
folder; the cache is ``OUTPUT_ROOT/.cache`` (see :mod:`planner.job.cache`).
"""
from __future__ import annotations

from pathlib import Path

import typer

from . import app

cache_app = typer.Typer(help="Check or empty the nightly job's work cache (OUTPUT_ROOT/.cache).",
                        no_args_is_help=True, rich_markup_mode=None)
app.add_typer(cache_app, name="cache")


def _root(target: Path) -> Path:
    from ..errors import InputError

    if target.is_file():
        from planner.job.config import load_job

        job = load_job(target)
        return job.resolve(job.job.output_root)
    if target.is_dir():
        return target
    raise InputError(f"{target}: neither a job file nor an output root folder; give jobs/nightly.toml "
                     "or the output root (e.g. outputs)")


@cache_app.command("verify")
def verify(
    target: Path = typer.Argument(..., help="Job file (TOML) or output root folder."),
    remove_bad: bool = typer.Option(False, "--remove-bad",
                                    help="Delete entries that fail and files that are not entries."),
) -> None:
    """Check every entry (name, kind, key, payload digest, decoding) as a run would; exit 1 if any fails."""
    from planner.job.cache import Cache
    from planner.job.publish import job_lock, output_root_errors

    root = _root(target)
    cache = Cache(root / ".cache")
    with output_root_errors(root):
        if remove_bad:
            with job_lock(root):
                rep = cache.verify(remove_bad=True)
        else:
            rep = cache.verify()
    for p, why in rep.bad:
        typer.echo(f"bad: {p}: {why}")
    for p in rep.foreign:
        typer.echo(f"not an entry: {p}")
    tail = f"; removed {rep.removed} file{'s' if rep.removed != 1 else ''}" if remove_bad else ""
    typer.echo(f"{cache.root}: {rep.good} good, {len(rep.bad)} bad, {len(rep.foreign)} not entries{tail}")
    if (rep.bad or rep.foreign) and not remove_bad:
        typer.echo("the next run recomputes bad entries; `planner cache verify --remove-bad` deletes them now",
                   err=True)
        raise typer.Exit(1)


@cache_app.command("clear")
def clear(target: Path = typer.Argument(..., help="Job file (TOML) or output root folder.")) -> None:
    """Delete the whole cache (the next run recomputes everything); published runs are not touched."""
    from planner.job.cache import Cache
    from planner.job.publish import job_lock, output_root_errors

    root = _root(target)
    cache = Cache(root / ".cache")
    with output_root_errors(root), job_lock(root):
        n = cache.clear()
    typer.echo(f"{cache.root}: removed {n} file{'s' if n != 1 else ''}")
