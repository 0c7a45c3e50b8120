"""Dataset files made once: a file whose inputs did not change since the previous run is that run's file.

A published dataset file does not name its run (the run's id and date are folders,
:func:`planner.io.parquet.place_in_run`), so the file a writer makes from the same stored results is the same
bytes on every night. Each group of files a writer makes in one call (a part of a partition of the tables',
the stopping patterns' or the closed loop's datasets, :func:`planner.job.steps.partition_keys`; a section's
occupation windows and day as it runs, :func:`planner.job.steps.section_written`) is named by a key that digests
what the bytes depend on (the writer, the code, the partition and part, and the keys of the units whose results
it writes). The run's manifest records, under ``made``, each group's key and the files it made, with their
SHA-256.

On the next night a group whose key is in the previous run's record is not written again: each of its files is
read and checked against the SHA-256 recorded, and then hard-linked into the staged run (copied where the output
root cannot hold links). A file that is missing or does not match, or a record that does not read as one, means
the group is written as on a cold night. ``--no-cache`` reuses nothing. A file is never changed in place once
written (every write is a new file renamed over the old name), so two runs that share a file by a link keep
the same bytes, and deleting an old run leaves the newer run's link.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import re
import shutil
from pathlib import Path
from typing import Callable

from planner.io.parquet import run_dataset_dir, without_run

_REL = re.compile(r"[a-z][a-z0-9_]*(/[a-z][a-z0-9_]*=[A-Za-z0-9][A-Za-z0-9._-]{0,63})+/part-[0-9]{1,6}\.parquet")
"""A dataset file's path in a run, without the run's folders (``table_d/line=L/direction=down/.../part-03.parquet``):
what a record may name, and nothing else (no ``..``, no absolute path)."""
_SHA = re.compile(r"[0-9a-f]{64}")


def file_sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(1 << 20):
            h.update(block)
    return h.hexdigest()


@dataclasses.dataclass(frozen=True)
class Previous:
    """The previous published run's made files: its folder and ``{group key: ((path, sha256), ...)}``."""

    run_dir: Path
    made: dict
    bundles: dict = dataclasses.field(default_factory=dict)
    """Its bundles' inputs keys (:func:`planner.job.bundle_reuse.recorded`)."""

    def of(self, keys) -> "Previous":
        """Only the groups of ``keys`` (what one writer task is sent)."""
        return Previous(self.run_dir, {k: self.made[k] for k in keys if k in self.made}, self.bundles)


def previous(root: Path, use_cache: bool) -> Previous | None:
    """The made files of the run ``root/latest`` points at, or None (``--no-cache``, no run, or a run whose manifest
    has no record that reads as one: then every file is written). Each record is checked: a path that is not a
    dataset file's, or a digest that is not one, drops the whole record."""
    from planner.job.publish import RUN_RE, latest_run

    last = latest_run(root) if use_cache else None
    if last is None or not RUN_RE.fullmatch(last):
        return None
    run_dir = Path(root) / last
    try:
        manifest = json.loads((run_dir / "manifest.json").read_text())
    except (OSError, ValueError):
        return None
    made = manifest.get("made") if isinstance(manifest, dict) else None
    if not isinstance(made, dict):
        return None
    out = {}
    for key, files in made.items():
        if not (isinstance(key, str) and _SHA.fullmatch(key) and isinstance(files, list)):
            return None
        if not all(isinstance(f, list) and len(f) == 2 and isinstance(f[0], str) and _REL.fullmatch(f[0])
                   and isinstance(f[1], str) and _SHA.fullmatch(f[1]) for f in files):
            return None
        out[key] = tuple((f[0], f[1]) for f in files)
    from planner.job.bundle_reuse import recorded

    return Previous(run_dir, out, recorded(manifest))


def _in_run(run_dir: Path, rel: str) -> Path:
    """Where a published run keeps the file ``rel`` (a path without the run's folders)."""
    name, _, rest = rel.partition("/")
    return run_dataset_dir(run_dir, name) / rest


def _reused(prev: Previous, key: str, stage: Path) -> list | None:
    """The group ``key``'s files linked from the previous run into ``stage`` when each is there with the digest
    recorded (``[(file, sha256)]``); else None, and nothing of the group is left in ``stage``."""
    files = prev.made.get(key)
    if files is None:
        return None
    for rel, sha in files:
        try:
            if file_sha256(_in_run(prev.run_dir, rel)) != sha:
                return None
        except (OSError, ValueError):  # not there, or not a published run's layout
            return None
    placed = []
    try:
        for rel, sha in files:
            dst = stage / rel
            dst.parent.mkdir(parents=True, exist_ok=True)
            src = _in_run(prev.run_dir, rel)
            try:
                os.link(src, dst)
            except OSError:  # another file system, or one without hard links
                shutil.copyfile(src, dst)
            placed.append((dst, sha))
    except OSError:
        for p, _ in placed:
            p.unlink(missing_ok=True)
        return None
    return placed


def made_once(key: str, prev: Previous | None, stage: Path, write: Callable[[], list[Path]]) -> tuple[list, list]:
    """A group of files in ``stage``: the previous run's (:func:`_reused`) or ``write()``'s. Returns (the files,
    the group's record: ``[path without the run's folders, sha256]`` each)."""
    stage = Path(stage)
    got = _reused(prev, key, stage) if prev is not None else None
    if got is None:
        got = [(Path(f), file_sha256(f)) for f in write()]
    return [f for f, _ in got], [[without_run(f.relative_to(stage).as_posix()), sha] for f, sha in got]
