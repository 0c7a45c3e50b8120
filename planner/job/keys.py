"""Which key signs a job's bundles: the configured production key, or a development key for test runs."""
from __future__ import annotations

import os
from pathlib import Path

from planner.errors import JobError
from planner.job.config import Job


def signing_key_path(job: Job, notes: list[str]) -> tuple[Path, bool]:
    """The private key to sign bundles with, and whether it is a development key.

    The job file's ``[bundles] signing_key``, else ``$PLANNER_SIGNING_KEY``; with
    neither, a development key under ``OUTPUT_ROOT/.dev-key`` only when the job
    says ``allow_development_key = true`` (else a :class:`JobError`). A
    configured key that is a development key (:func:`planner.bundle.signing.is_development_key`:
    in a ``.dev-key`` folder, or marked beside it) counts as one.
    """
    from planner.bundle.signing import DEV_KEY_DIR, generate_keypair, is_development_key

    dev = job.resolve(job.job.output_root) / DEV_KEY_DIR
    p = None
    if job.bundles.signing_key:
        p = job.resolve(job.bundles.signing_key)
        if not p.is_file():
            raise JobError(f"{job.path}: [bundles] signing_key: {p} not found; "
                           "create one with `planner keys generate DIR`")
    elif os.environ.get("PLANNER_SIGNING_KEY"):
        p = Path(os.environ["PLANNER_SIGNING_KEY"])
        if not p.is_file():
            raise JobError(f"PLANNER_SIGNING_KEY: {p} not found")
    if p is not None:
        is_dev = is_development_key(p)
        if is_dev and not job.bundles.allow_development_key:
            raise JobError(f"{job.path}: [bundles] signing_key: {p} is the development key; use a production key "
                           "(`planner keys generate DIR`) or set allow_development_key = true for test runs")
        if is_dev:
            notes.append(f"bundles signed with the DEVELOPMENT key {p}: marked development, refused by vehicles")
        return p, is_dev
    if not job.bundles.allow_development_key:
        raise JobError(f"{job.path}: [bundles] no signing key: set signing_key to a production key "
                       "(`planner keys generate DIR`) or PLANNER_SIGNING_KEY, or allow_development_key = true "
                       "for test runs")
    key = dev / "signing_key.pem"
    made = not key.is_file()
    if made:
        generate_keypair(dev, development=True)
    notes.append(f"no signing key configured: bundles signed with the {'new ' if made else ''}DEVELOPMENT key {key} "
                 "(allow_development_key = true); they are marked development and vehicles refuse them")
    return key, True


__all__ = ["signing_key_path"]
