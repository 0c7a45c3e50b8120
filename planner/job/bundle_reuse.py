"""A bundle's steps' tables taken from the previous run's bundle when the datasets they come from did not change.

A bundle holds the line's own tables (restrictions, ATS-P telegrams, maximum profile, beacons, timetable: made
from the line database, small) and the steps' tables (evaluation points, tables (a) to (d), stop summary and
samples: read from the tables' and stops' datasets, most of its bytes and of its build time). Every night's
manifest is new (its release, the line's digest), so every bundle is signed again; but a steps' table whose
dataset's files are the previous run's (:mod:`planner.job.made`) is the same bytes.

Each of a bundle's steps' tables has its *inputs key*, which digests what its bytes depend on: the code, the
Parquet writer's version, the bundle's line, direction and train type, the table's name and each file of its
dataset's partition by path and SHA-256 (the records of :mod:`planner.job.made`). The run's manifest records the
keys under ``bundle_inputs`` (bundle file name → table → key). On the next night a table whose key is the one
recorded is taken from the previous run's bundle, read with its signature checked against this run's public key
and each member against the SHA-256 its signed manifest lists (:func:`planner.bundle.verify.read_signed`), as long
as every table it is cross-checked with (:data:`planner.bundle.contents.CROSS_CHECKED`) is either taken too (the
pair was checked when those bytes were signed together) or one the build decodes anyway (the evaluation points,
the stop summary: the pair is checked again). So an edit that touches a leg's tables (a) to (c) encodes those
three again and takes table (d) and the stops' tables, most of the bytes, as they were. Anything else (another
key, a bundle missing or altered, a file without a record) means the table is read from its dataset and encoded,
as on a cold night; either way the bundle is the same bytes.
"""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

from planner.job.made import _SHA

BUNDLE_FILE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}_(down|up)_[A-Za-z0-9][A-Za-z0-9._-]{0,63}\.pdb")
"""A bundle's file name, what a record may name."""


def recorded(manifest: dict) -> dict:
    """The previous run's ``bundle_inputs`` (bundle file name → steps' table → inputs key), read strictly: a name
    that is not a bundle's, a table that is not a steps' table or a key that is not a digest drops the whole record
    (nothing is reused)."""
    from planner.bundle.container import STEP_TABLES

    rec = manifest.get("bundle_inputs")
    if not isinstance(rec, dict) or not all(
            isinstance(k, str) and BUNDLE_FILE.fullmatch(k) and isinstance(v, dict)
            and all(t in STEP_TABLES and isinstance(x, str) and _SHA.fullmatch(x) for t, x in v.items())
            for k, v in rec.items()):
        return {}
    return {k: dict(v) for k, v in rec.items()}


def taken(same: set[str]) -> set[str]:
    """Of the steps' tables whose keys are the recorded ones (``same``), those a bundle may take from the previous
    bundle: each table cross-checked with another (:data:`planner.bundle.contents.CROSS_CHECKED`) is taken only when
    that other one is taken too or is decoded by the build all the same (:data:`planner.bundle.container.DECODED_GIVEN`),
    so that no check between a taken table and one encoded anew is left out. Repeated until nothing more drops out."""
    from planner.bundle.container import DECODED_GIVEN
    from planner.bundle.contents import CROSS_CHECKED

    keep = set(same)
    while True:
        drop = {x for a, b in CROSS_CHECKED for x, other in ((a, b), (b, a))
                if x in keep and x not in DECODED_GIVEN and other not in keep}
        if not drop:
            return keep
        keep -= drop


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

    def inputs_keys(self, direction: str, train_type: str) -> dict[str, str]:
        """Each steps' table's inputs key; a table one of whose files has no record has none (it is not recorded,
        so never taken)."""
        from planner.bundle.assemble import TABLE_SOURCES
        from planner.job.publish import digest
        from planner.job.units import code_digest
        import pyarrow as pa

        keys = {}
        for name in TABLE_SOURCES["tables"] + TABLE_SOURCES["stops"]:
            folder = self.stage / name / f"line={self.line_id}" / f"direction={direction}" / f"train_type={train_type}"
            files = []
            for f in sorted(folder.glob("*.parquet")) if folder.is_dir() else []:
                rel = f.relative_to(self.stage).as_posix()
                if rel not in self.shas:
                    break
                files.append([rel, self.shas[rel]])
            else:
                keys[name] = digest(["bundle_member", code_digest(), pa.__version__, self.line_id, direction,
                                     train_type, name, files])
        return keys

    def __call__(self, direction: str, train_type: str) -> dict | None:
        from planner.bundle.manifest import bundle_name
        from planner.bundle.signing import load_private_key
        from planner.bundle.verify import Expect, read_signed
        from planner.errors import BundleError

        keys = self.inputs_keys(direction, train_type)
        name = bundle_name(self.line_id, direction, train_type)
        self.keys[name] = dict(sorted(keys.items()))
        before = self.before.get(name, {}) if self.previous is not None else {}
        same = taken({t for t, k in keys.items() if before.get(t) == k})
        if not same:
            return None
        try:
            _, members = read_signed(self.previous / "bundles" / name, load_private_key(self.key_path).public_key(),
                                     expect=Expect(f"{self.line_id}/{direction}/{train_type}", allow_dev=True,
                                                   check_time=False))
        except (BundleError, OSError):  # another key, or a bundle missing or altered: built from the datasets
            return None
        return {t: members[f"{t}.parquet"] for t in sorted(same) if f"{t}.parquet" in members}


__all__ = ["BUNDLE_FILE", "BundleReuse", "recorded", "taken"]
