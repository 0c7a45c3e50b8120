"""Run folders, atomic publication and the work cache of the nightly job.

Layout under the output root::

    outputs/
      latest -> r0007-3f9a2c01d4        (symlink, swapped atomically)
      r0006-.../  r0007-.../            (complete runs; the last N are kept)
      .staging-r0008-.../               (a run being written; never read by users)
      .cache/<kind>/<ab>/<key>.pce      (results keyed by the digest of their inputs; planner.job.cache)
      .lock                             (one job at a time per output root)

A run is written entirely under ``.staging-<run_id>`` and renamed to
``<run_id>`` only when every step succeeded; then ``latest`` is re-pointed
with ``os.replace`` of a fresh symlink, which is atomic on POSIX. A failing or
killed run therefore never changes ``latest`` nor touches a published run;
its staging folder is removed by the next run.

A file-system failure (a full disk, a read-only or unwritable output root)
ends the job with one :class:`JobError` line naming the path and the fix
(:func:`output_root_errors`); ``latest`` is untouched.
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import errno
import os
import re
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator


from planner.io.atomic import STAGING_PREFIX, _fsync_dir, fsync_tree, remove_staging
from planner.job.cache import Cache  # noqa: F401  (the cache lived here; planner.cache is its home now)
from planner.errors import JobError

RUN_RE = re.compile(r"^r(\d{4,})-([0-9a-f]{10})$")


def canonical_json(obj: Any) -> bytes:
    """Stable JSON bytes: sorted keys, no spaces, floats as Python repr (exact round trip)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, default=_default).encode()


def _default(o: Any):
    import dataclasses

    import numpy as np

    if dataclasses.is_dataclass(o):
        return {f.name: getattr(o, f.name) for f in dataclasses.fields(o)}
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, Path):
        return o.as_posix()
    raise TypeError(f"cannot digest {type(o).__name__}")


def digest(obj: Any) -> str:
    """SHA-256 hex digest of ``obj``'s canonical JSON."""
    return hashlib.sha256(canonical_json(obj)).hexdigest()


# --- runs and publication -----------------------------------------------------
def list_runs(root: Path) -> list[str]:
    """Published run ids under ``root``, oldest first."""
    root = Path(root)
    if not root.is_dir():
        return []
    runs = [p.name for p in root.iterdir() if p.is_dir() and not p.is_symlink() and RUN_RE.match(p.name)]
    return sorted(runs, key=lambda r: int(RUN_RE.match(r).group(1)))


def latest_run(root: Path) -> str | None:
    """The run ``latest`` points at, or None."""
    link = Path(root) / "latest"
    if link.is_symlink():
        target = os.readlink(link)
        if (Path(root) / target).is_dir():
            return Path(target).name
    return None


def next_run_id(root: Path, inputs_digest: str) -> str:
    """``r<seq>-<digest10>``: a sequence number after every run seen, and the inputs digest."""
    root = Path(root)
    seqs = [int(RUN_RE.match(r).group(1)) for r in list_runs(root)]
    if root.is_dir():
        for p in root.iterdir():
            m = re.match(r"^\.staging-r(\d{4,})-", p.name)
            if m:
                seqs.append(int(m.group(1)))
    return f"r{(max(seqs) + 1) if seqs else 1:04d}-{inputs_digest[:10]}"


_FIXES = {
    errno.ENOSPC: ("no space left on device", "free space there or set [job] output_root to a larger disk"),
    errno.EDQUOT: ("disk quota exceeded", "free space there or set [job] output_root to a larger disk"),
    errno.EROFS: ("read-only file system", "mount it read-write or set [job] output_root to a writable folder"),
    errno.EACCES: ("permission denied", "give the planner write access or set [job] output_root elsewhere"),
    errno.EPERM: ("operation not permitted", "give the planner write access or set [job] output_root elsewhere"),
}


def _errno_of(e: OSError) -> int | None:
    if e.errno is not None:
        return e.errno
    text = str(e)  # pyarrow's IO errors carry the reason in the message only
    for code, (why, _) in _FIXES.items():
        if why.lower() in text.lower() or os.strerror(code).lower() in text.lower():
            return code
    return None


@contextmanager
def output_root_errors(root: Path) -> Iterator[None]:
    """Turn a file-system error under ``root`` into one :class:`JobError` line naming the path and the fix.

    A full disk, a read-only file system or missing permissions end the job
    here; ``latest`` has not been touched (publication is the last step). The
    staging folder is removed by :func:`job_lock` at once when the disk is full
    (to give the space back), else by the next run.
    """
    root = Path(root)
    try:
        yield
    except OSError as e:
        code = _errno_of(e)
        text = str(e).splitlines()[0] if str(e) else type(e).__name__
        why, fix = _FIXES.get(code, (e.strerror or text, "check the path and the disk"))
        # a copy's error names its source as filename and its destination as filename2: the one in
        # the output root is where the disk is full, not the line database the copy read
        named = [Path(os.fsdecode(f)) for f in (e.filename2, e.filename) if f not in (None, "")]
        where = next((f for f in named if _under(f, root)), named[-1] if named else root)
        last = latest_run(root)
        kept = f"latest still points at {last}" if last else "nothing was published"
        if not _under(where, root):  # not the output root: an input or a key file
            raise JobError(f"{where}: {why}; check that path, then run again ({kept})") from None
        raise JobError(f"{where}: {why} (output root {root}); {fix}, then run again ({kept})") from None


def _under(path: Path, root: Path) -> bool:
    try:
        Path(os.path.abspath(path)).relative_to(os.path.abspath(root))
        return True
    except ValueError:
        return False


@contextmanager
def job_lock(root: Path) -> Iterator[None]:
    """One job per output root at a time (an advisory lock the kernel drops if we die)."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    fd = os.open(root / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise JobError(f"{root}: another planner job is running on this output root; wait for it") from None
        try:
            yield
        except OSError as e:
            if _errno_of(e) in (errno.ENOSPC, errno.EDQUOT):
                clean_stale_staging(root)  # give the space back now (still under the lock)
            raise
    finally:
        os.close(fd)


def clean_stale_staging(root: Path) -> list[str]:
    """Remove staging folders left by failed or killed runs (call under the job lock)."""
    return remove_staging(root)


def staging_dir(root: Path, run_id: str) -> Path:
    p = Path(root) / f"{STAGING_PREFIX}{run_id}"
    p.mkdir(parents=True, exist_ok=False)
    return p


def publish(root: Path, staging: Path, run_id: str, keep: int) -> Path:
    """Make a complete staged run visible: rename it, swap ``latest``, prune old runs.

    Returns the published run folder.
    """
    root = Path(root)
    fsync_tree(staging)  # every file and folder on disk before the run becomes visible
    final = root / run_id
    os.rename(staging, final)
    tmp_link = root / f".latest-{run_id}.tmp"
    if tmp_link.is_symlink() or tmp_link.exists():
        tmp_link.unlink()
    os.symlink(run_id, tmp_link)
    os.replace(tmp_link, root / "latest")
    _fsync_dir(root)
    runs = list_runs(root)
    for old in runs[: max(0, len(runs) - keep)]:
        if old != run_id:
            shutil.rmtree(root / old, ignore_errors=True)
    return final


# ---------------------------------------------------------------------------
# The run's manifest
# ---------------------------------------------------------------------------


def conflicts_status(job, line) -> str:
    """Whether the run checks the line's conflicts: ``checked``, ``no track network`` or ``disabled`` (the manifest's)."""
    if not job.conflicts.enabled:
        return "disabled"
    return "checked" if line.network is not None else "no track network"


def _release_record(release) -> dict | None:
    from planner.bundle.manifest import format_time

    if release is None:
        return None
    return {"version": release.version, "built_at": format_time(release.built_at_s),
            "expires": format_time(release.expires_s),
            "key_kind": "development" if release.development else "production"}


def manifest_head(job, lines, run_id: str, inputs: str, run_date: str = "", day: dict | None = None) -> dict:
    """The manifest's fields that are known when the run starts: the run, its day, inputs, code and parameters."""
    import importlib.metadata
    import platform

    import numpy
    import pyarrow

    from planner import __version__
    from planner.job.units import code_digest, kernel_backends

    return {
        "run_id": run_id,
        "run_date": run_date,
        "operating_day": day,
        "job": job.job.name,
        "inputs_digest": inputs,
        "code_digest": code_digest(),
        "software": {"planner": __version__, "python": platform.python_version(),
                     "numpy": numpy.__version__, "pyarrow": pyarrow.__version__,
                     "numba": importlib.metadata.version("numba"), "kernels": kernel_backends()},
        "lines": [{"line_id": ln.line_id, "path": Path(p).as_posix(), "source_digest": ln.source_digest,
                   "conflicts": conflicts_status(job, ln)}
                  for ln, p in zip(lines, job.job.lines)],
        "parameters": job.parameters(),
    }


def write_manifest(stage: Path, timings, summary) -> None:
    """The staged run's ``manifest.json`` (:func:`manifest_head` and what the run made: ``summary``, a
    :class:`planner.job.pipeline.RunSummary`) and its ``README.md``."""
    from planner.io.atomic import write_bytes_atomic

    manifest = {
        **summary.head,
        "timings_s": dict(timings),
        "units_computed": dict(summary.computed),
        "units_reused": dict(summary.reused),
        "rows": dict(sorted(summary.rows.items())),
        "flags": dict(sorted(summary.flags.items())),
        "bundles": sorted(summary.bundles),
        "bundles_release": _release_record(summary.release),
        "made": dict(sorted(summary.made.items())),
        "bundle_inputs": dict(sorted(summary.bundle_inputs.items())),
    }
    write_bytes_atomic(stage / "manifest.json", canonical_json(manifest) + b"\n")
    from planner.report.catalog import readme

    write_bytes_atomic(stage / "README.md", readme().encode())
