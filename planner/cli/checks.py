"""Checks every command makes *before* it computes: output paths, option ranges, codes.

An output path that cannot be written must fail in the first second with one
line naming the option and the fix, not after minutes of computing with a
traceback (``NotADirectoryError``, ``PermissionError``). These checks create
nothing; the writers still write atomically.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Iterable, Optional, Sequence

from ..errors import InputError


def _nearest_existing(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists."""
    p = Path(os.path.abspath(path))
    while not os.path.lexists(p) and p != p.parent:
        p = p.parent
    return p


def _writable_folder_at(path: Path, option: str, what: str, shown: Optional[Path] = None) -> None:
    """``path`` is (or can become) a folder we may write in; else InputError naming ``option``."""
    base = _nearest_existing(path)
    path = path if shown is None else shown
    if not base.is_dir():
        raise InputError(f"{option} {path}: {base} is a file, not a folder; give a folder path for the {what}")
    try:  # a probe: permissions, read-only and pseudo file systems (/proc) all show here
        fd, tmp = tempfile.mkstemp(prefix=".planner-probe-", dir=base)
        os.close(fd)
        os.unlink(tmp)
    except OSError as e:
        raise InputError(f"{option} {path}: cannot write in {base} ({e.strerror or e}); "
                         f"choose a folder you can write to for the {what}") from None


def check_out_dir(path: Optional[Path], option: str = "--out", what: str = "output") -> None:
    """An output *folder*: an existing folder, or a path whose nearest existing ancestor is a writable folder.

    Raises
    ------
    InputError
        ``path`` is an existing file, lies below a file, or cannot be created (permissions,
        a read-only file system such as /proc).
    """
    if path is None:
        return
    p = Path(path)
    if os.path.lexists(p) and not p.is_dir():
        raise InputError(f"{option} {p}: exists and is not a folder; give a folder (it is created if missing)")
    _writable_folder_at(p, option, what)


def check_out_file(path: Optional[Path], option: str, suffix: Optional[str] = None, what: str = "file") -> None:
    """An output *file*: not a folder, with ``suffix`` if given, in a folder that exists or can be created."""
    if path is None:
        return
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{option} {p}: is a folder; give a file name (e.g. {p / ('out' + (suffix or ''))})")
    if suffix is not None and p.suffix.lower() != suffix:
        raise InputError(f"{option} {p}: the {what} is written as {suffix[1:].upper()}; give a file name "
                         f"ending in {suffix}")
    _writable_folder_at(p.parent, option, what, shown=p)


def check_fraction(value: float, option: str, meaning: str) -> None:
    """A factor that must lie in [0, 1] (e.g. ``--load``: 0 empty … 1 full)."""
    if not (0.0 <= value <= 1.0):
        raise InputError(f"{option} must lie between 0 and 1 ({meaning}), got {value:g}")


def station_code(line, text: str, option: str) -> str:
    """The line's station id for ``text`` (case-insensitive); the error names ``option``."""
    try:
        return line.station(text).station_id
    except InputError as e:
        raise type(e)(f"{option} {text}: {e}") from None


def train_type_code(line, text: str, option: str = "--train-type") -> str:
    """The line's train-type id for ``text`` (case-insensitive); the error names ``option``."""
    try:
        return line.train_type(text).train_type
    except InputError as e:
        raise type(e)(f"{option} {text}: {e}") from None


def train_type_codes(line, texts: Optional[Sequence[str]]) -> Optional[list[str]]:
    """:func:`train_type_code` of each (None stays None: every type)."""
    if not texts:
        return None
    return [train_type_code(line, t) for t in texts]


def check_jobs(n: int, option: str = "--jobs") -> None:
    if n == 0 or n < -1:
        raise InputError(f"{option} must be -1 (all cores) or ≥ 1, found {n}")


__all__: Iterable[str] = ["check_out_dir", "check_out_file", "check_fraction", "station_code", "train_type_code",
                          "train_type_codes", "check_jobs"]


JOB_HELP = ("Job file: use the line as the nightly job plans it on its operating day (the day's temporary "
            "restrictions and trains), so the answer is the published night's.")
DAY_HELP = "With --job: plan this operating day (YYYY-MM-DD) instead of the job's."


DAY_NOTES: list[str] = []
"""What :func:`day_line` says of the line a command computed with: printed on stderr after the command's own output
when it succeeds (``planner.cli._Group``), never before an error (a refused command prints its one line only)."""


def day_line(line, job_file: Optional[Path], day: Optional[str], lifted: Optional[dict] = None):
    """The line a one-off command computes with: with ``--job`` (and ``--day``) the job's operating day's line
    (:func:`planner.job.day.line_on_day`), said in one line on stderr; without, the line as its database has it,
    and a line on stderr saying that no day's temporary restrictions are in it. ``lifted``, when given, gets the
    restrictions lifted per train that day (the conflict check's, as the night's)."""
    from planner.errors import InputError

    if job_file is None:
        if day:
            raise InputError("--day needs --job JOB.toml: the job names the line's daily feed and time zone")
        DAY_NOTES.append("note: the line as its database has it, no operating day's temporary restrictions (--job "
                         "JOB.toml [--day D] plans that day's line, as the nightly job does)")
        return line
    from planner.job.config import load_job
    from planner.job.day import line_on_day, resolve_day, with_day

    job = load_job(job_file)
    job = resolve_day(with_day(job, day) if day else job)
    out, said, off = line_on_day(job, line)
    if lifted is not None:
        lifted.update(off)
    DAY_NOTES.append(f"note: {said}")
    return out

