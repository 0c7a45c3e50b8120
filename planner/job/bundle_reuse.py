"""A bundle's steps' tables taken from the previous run's bundle when the datasets they come from did not change.

A bundle holds the line's own tables (restrictions, ATS-P telegrams, maximum profile, beacons, timetable: made
from the line database, small) and the steps' tables (evaluation points, tables (a) to (d), stop summary and
samples: read from the tables' and stops' datasets, most of its bytes and of its build time). Every night's
manifest is new (its release, the line's digest), so every bundle is signed again; but the steps' tables of a
bundle whose datasets' files are the previous run's (:mod:`planner.job.made`) are the same bytes.

Each bundle's *inputs key* digests what those bytes depend on: the code, the Parquet writer's version, the
bundle's line, direction and train type, and each file of its datasets' partitions by path and SHA-256 (the
records of :mod:`planner.job.made`). The run's manifest records the keys under ``bundle_inputs``. On the next
night a bundle whose key is the one recorded takes those members from the previous run's bundle, read with its
signature checked against this run's public key and each member against the SHA-256 its signed manifest lists
(:func:`planner.bundle.verify.read_signed`); only the line's own tables are made again and the manifest signed
(:func:`planner.bundle.container.build_line`). Anything else (another key, a bundle missing or altered, a file
without a record) means the tables are read from the datasets and encoded, as on a cold night.
"""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from planner.job.made import _SHA

BUNDLE_FILE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}_(down|up)_[A-Za-z0-9][A-Za-z0-9._-]{0,63}\.pdb")
"""A bundle's file name, what a record may name."""


def recorded(manifest: dict) -> dict:
    """The previous run's ``bundle_inputs`` (bundle file name → inputs key), read strictly: a name that is not a
    bundle's or a key that is not a digest drops the whole record (nothing is reused)."""
    rec = manifest.get("bundle_inputs")
    if not isinstance(rec, dict) or not all(isinstance(k, str) and BUNDLE_FILE.fullmatch(k) and isinstance(v, str)
                                            and _SHA.fullmatch(v) for k, v in rec.items()):
        return {}
    return dict(rec)


@dataclasses.dataclass
class BundleReuse:
    """``build_line``'s ``reused`` for one line of the nightly job, run where the bundles are built: this run's
    inputs key of each bundle (kept in :attr:`keys` for the manifest) and, when it is the previous run's, that
    bundle's steps' members."""

    stage: Path
    """The staged run (its datasets without the run's folders)."""
    line_id: str
    shas: dict
    """This run's dataset files by path without the run's folders → SHA-256 (the manifest's ``made`` records)."""
    key_path: Path
    """The signing key: the previous bundle is checked against its public half."""
    previous: Path | None = None
    """The previous published run's folder, when it recorded keys."""
    before: dict = dataclasses.field(default_factory=dict)
    """The previous run's record (:func:`recorded`)."""
    keys: dict = dataclasses.field(default_factory=dict)

    def inputs_key(self, direction: str, train_type: str) -> str | None:
        """The bundle's inputs key, or None when a file of its datasets has no record (then it is not recorded)."""
        from planner.bundle.assemble import TABLE_SOURCES
        from planner.job.publish import digest
        from planner.job.units import code_digest
        import pyarrow as pa

        files = []
        for name in TABLE_SOURCES["tables"] + TABLE_SOURCES["stops"]:
            folder = self.stage / name / f"line={self.line_id}" / f"direction={direction}" / f"train_type={train_type}"
            for f in sorted(folder.glob("*.parquet")) if folder.is_dir() else []:
                rel = f.relative_to(self.stage).as_posix()
                if rel not in self.shas:
                    return None
                files.append([rel, self.shas[rel]])
        return digest(["bundle_inputs", code_digest(), pa.__version__, self.line_id, direction, train_type, files])

    def __call__(self, direction: str, train_type: str) -> dict | None:
        from planner.bundle.container import STEP_TABLES
        from planner.bundle.manifest import bundle_name
        from planner.bundle.signing import load_private_key
        from planner.bundle.verify import Expect, read_signed
        from planner.errors import BundleError

        key = self.inputs_key(direction, train_type)
        if key is None:
            return None
        name = bundle_name(self.line_id, direction, train_type)
        self.keys[name] = key
        if self.previous is None or self.before.get(name) != key:
            return None
        try:
            _, members = read_signed(self.previous / "bundles" / name, load_private_key(self.key_path).public_key(),
                                     expect=Expect(f"{self.line_id}/{direction}/{train_type}", allow_dev=True,
                                                   check_time=False))
        except (BundleError, OSError):  # another key, or a bundle missing or altered: built from the datasets
            return None
        return {t: members[f"{t}.parquet"] for t in STEP_TABLES if f"{t}.parquet" in members}


__all__ = ["BUNDLE_FILE", "BundleReuse", "recorded"]
