"""Bundles a vehicle can trust (issue 21): identity, key id, key kind, rollback, expiry.

Each attack of the issue is replayed against ``verify_bundle`` and the CLI and
must be refused with its own one-line reason; a legitimate newer bundle is
accepted. Bundles are built by the planner's builder, or forged by the
independent writer in ``test_bundle_support`` when the attack needs a manifest
the builder would never write (a lying ``key_id``).
"""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from planner.bundle.assemble import line_tables
from planner.bundle.container import build_bundle
from planner.bundle.manifest import Release, build_time_s, parse_time
from planner.bundle.verify import verify_bundle
from planner.bundle import signing
from planner.line import testing
from planner.errors import BundleError
from test_bundle_support import BUILT_AT_S, LINE_ID, forge, release

DAY = 86400
JAN_02 = "2026-01-02T00:00:00Z"  # one day after BUILT_AT_S, well inside every test release


@pytest.fixture(scope="module")
def small_line():
    return testing.line(line_id=LINE_ID, train_types=[testing.train_type("E10")])


def build(line, out: Path, key, direction="down", **rel) -> Path:
    info = build_bundle(line_tables(line, direction, "E10"), line_id=LINE_ID, direction=direction,
                        train_type="E10", out_dir=out, private_key=key, release=release(**rel))
    return Path(info.path)


def run_cli(*args):
    from typer.testing import CliRunner

    from planner.cli import app

    return CliRunner().invoke(app, list(map(str, args)))


def one_line_error(r) -> str:
    lines = [x for x in r.output.splitlines() if x.strip()]
    assert r.exit_code != 0 and len(lines) == 1 and lines[0].startswith("error: bundle"), r.output
    assert "Traceback" not in r.output
    return lines[0]


# --- 1. identity: a bundle renamed to another target's file name --------------------------
def test_renamed_bundle_is_refused(tmp_path, keys, small_line):
    up = build(small_line, tmp_path / "b", keys[0], direction="up")
    renamed = tmp_path / f"{LINE_ID}_down_E10.pdb"
    shutil.copy(up, renamed)
    with pytest.raises(BundleError, match=f"bundle is for {LINE_ID}/up/E10, not the expected {LINE_ID}/down/E10"):
        verify_bundle(renamed, keys[1], expect=f"{LINE_ID}/down/E10", at=JAN_02)
    r = run_cli("bundle", "verify", renamed, "--public-key", keys[1], "--expect", f"{LINE_ID}/down/E10",
                "--at", JAN_02)
    assert "not the expected tl/down/E10" in one_line_error(r)
    # the same file checked for what it really is passes
    assert verify_bundle(renamed, keys[1], expect=f"{LINE_ID}/up/E10", at=JAN_02).direction == "up"


@pytest.mark.parametrize("bad", ["tl/down", "tl/sideways/E10", "tl/down/E10/x", "../x/down/E10", ""])
def test_malformed_expect_is_a_one_line_error(tmp_path, keys, small_line, bad):
    path = build(small_line, tmp_path / "b", keys[0])
    r = run_cli("bundle", "verify", path, "--public-key", keys[1], "--expect", bad, "--at", JAN_02)
    lines = [x for x in r.output.splitlines() if x.strip()]
    assert r.exit_code != 0 and len(lines) == 1 and "LINE/DIRECTION/TYPE" in lines[0]


# --- 2. key id: a manifest that claims someone else's key ----------------------------------
def test_manifest_claiming_another_key_id_is_refused(tmp_path, keys, small_line):
    evil = Ed25519PrivateKey.generate()
    real_id = signing.public_key_id(keys[2].public_key())
    evil_id = signing.public_key_id(evil.public_key())
    raw = forge(line_tables(small_line, "down", "E10"), evil, key_id=real_id)
    p = tmp_path / f"{LINE_ID}_down_E10.pdb"
    p.write_bytes(raw)
    # verified with the attacker's own public key the signature is fine: only the key id check stops it
    with pytest.raises(BundleError, match=f"manifest names signing key {real_id[:16]}, but it was verified "
                                          f"with key {evil_id[:16]}"):
        verify_bundle(p, evil.public_key(), expect=f"{LINE_ID}/down/E10", at=JAN_02)
    evil_pub = tmp_path / "evil.pub.pem"
    from cryptography.hazmat.primitives import serialization

    evil_pub.write_bytes(evil.public_key().public_bytes(serialization.Encoding.PEM,
                                                        serialization.PublicFormat.SubjectPublicKeyInfo))
    r = run_cli("bundle", "verify", p, "--public-key", evil_pub, "--expect", f"{LINE_ID}/down/E10", "--at", JAN_02)
    assert "the manifest lies about its signer" in one_line_error(r)
    # and with the real key the signature itself fails
    with pytest.raises(BundleError, match="signature does not match"):
        verify_bundle(p, keys[1], expect=f"{LINE_ID}/down/E10", at=JAN_02)


# --- 3. development key ---------------------------------------------------------------------
def test_development_key_bundle_is_refused_unless_allowed(tmp_path, keys, small_line):
    p = build(small_line, tmp_path / "b", keys[0], development=True)
    with pytest.raises(BundleError, match="signed with a development key: not for service"):
        verify_bundle(p, keys[1], expect=f"{LINE_ID}/down/E10", at=JAN_02)
    r = run_cli("bundle", "verify", p, "--public-key", keys[1], "--expect", f"{LINE_ID}/down/E10", "--at", JAN_02)
    assert "development key" in one_line_error(r)
    info = verify_bundle(p, keys[1], expect=f"{LINE_ID}/down/E10", at=JAN_02, allow_dev=True)
    assert info.key_kind == "development"
    r = run_cli("bundle", "verify", p, "--public-key", keys[1], "--expect", f"{LINE_ID}/down/E10", "--at", JAN_02,
                "--allow-dev")
    assert r.exit_code == 0 and "DEVELOPMENT KEY" in r.output, r.output


def test_production_is_what_the_builder_writes_by_default(tmp_path, keys, small_line):
    p = build(small_line, tmp_path / "b", keys[0])
    assert verify_bundle(p, keys[1], at=JAN_02).key_kind == "production"


# --- 4. rollback -----------------------------------------------------------------------------
def test_older_bundle_is_refused_as_rollback(tmp_path, keys, small_line):
    old = build(small_line, tmp_path / "old", keys[0], version=5)
    with pytest.raises(BundleError, match="bundle version 5 is older than the installed version 6 "
                                          "\\(rollback refused\\)"):
        verify_bundle(old, keys[1], expect=f"{LINE_ID}/down/E10", min_version=6, at=JAN_02)
    r = run_cli("bundle", "verify", old, "--public-key", keys[1], "--expect", f"{LINE_ID}/down/E10",
                "--min-version", 6, "--at", JAN_02)
    assert "rollback refused" in one_line_error(r)
    # the installed release itself (same version) is accepted: reinstalling it is no rollback
    assert verify_bundle(old, keys[1], min_version=5, at=JAN_02).bundle_version == 5


# --- 5. expiry (freeze) -------------------------------------------------------------------------
def test_expired_bundle_is_refused(tmp_path, keys, small_line):
    p = build(small_line, tmp_path / "b", keys[0], valid_days=30)  # built 2026-01-01, expires 2026-01-31
    last_second = parse_time("2026-01-30T23:59:59Z")
    assert verify_bundle(p, keys[1], at=last_second).expires == "2026-01-31T00:00:00Z"
    with pytest.raises(BundleError, match="bundle expired at 2026-01-31T00:00:00Z \\(checked at "
                                          "2026-01-31T00:00:00Z"):
        verify_bundle(p, keys[1], expect=f"{LINE_ID}/down/E10", at=last_second + 1)
    r = run_cli("bundle", "verify", p, "--public-key", keys[1], "--expect", f"{LINE_ID}/down/E10",
                "--at", "2026-03-01T00:00:00Z")
    assert "expired at 2026-01-31T00:00:00Z" in one_line_error(r)
    # without --at the vehicle's clock is used: a bundle built in 2020 for 30 days is expired today
    stale = build(small_line, tmp_path / "stale", keys[0], built_at_s=parse_time("2020-01-01"),
                  valid_days=30)
    with pytest.raises(BundleError, match="expired at 2020-01-31T00:00:00Z"):
        verify_bundle(stale, keys[1])


# --- the legitimate update ---------------------------------------------------------------------
def test_legitimate_newer_bundle_is_accepted(tmp_path, keys, small_line):
    installed = Release.issue(BUILT_AT_S, valid_days=30)
    newer = Release.issue(BUILT_AT_S + DAY, valid_days=30)
    assert newer.version > installed.version
    info = build_bundle(line_tables(small_line, "down", "E10"), line_id=LINE_ID, direction="down",
                        train_type="E10", out_dir=tmp_path, private_key=keys[2], release=newer)
    got = verify_bundle(info.path, keys[1], expect=f"{LINE_ID}/down/E10", min_version=installed.version,
                        at=BUILT_AT_S + 2 * DAY)
    assert (got.bundle_version, got.built_at, got.expires, got.key_kind) == (
        20260102000000, "2026-01-02T00:00:00Z", "2026-02-01T00:00:00Z", "production")
    r = run_cli("bundle", "verify", info.path, "--public-key", keys[1], "--expect", f"{LINE_ID}/down/E10",
                "--min-version", installed.version, "--at", "2026-01-03T00:00:00Z")
    assert r.exit_code == 0 and r.output.startswith("OK: tl/down/E10 version 20260102000000"), r.output


# --- version and build time: monotonic, yet reproducible ------------------------------------------
@pytest.mark.parametrize("earlier, later", [
    ("2026-01-01T00:00:00Z", "2026-01-01T00:00:01Z"),
    ("2026-12-31T23:59:59Z", "2027-01-01T00:00:00Z"),
    ("2026-01-31T23:00:00Z", "2026-02-01T01:00:00Z"),
])
def test_versions_grow_with_the_build_time(earlier, later):
    a, b = (Release.issue(parse_time(t)) for t in (earlier, later))
    assert a.version < b.version
    # the version reads as the UTC build time
    assert str(a.version) == earlier.replace("-", "").replace(":", "").replace("T", "").rstrip("Z")


def test_same_inputs_and_release_give_the_same_bytes_and_the_build_time_is_signed(tmp_path, keys, small_line):
    a = build(small_line, tmp_path / "a", keys[0]).read_bytes()
    b = build(small_line, tmp_path / "b", keys[0]).read_bytes()
    c = build(small_line, tmp_path / "c", keys[0], built_at_s=BUILT_AT_S + 1).read_bytes()
    assert a == b and a != c


def test_build_time_comes_from_source_date_epoch():
    assert build_time_s({"SOURCE_DATE_EPOCH": "1767225600"}) == BUILT_AT_S
    with pytest.raises(BundleError, match="SOURCE_DATE_EPOCH"):
        build_time_s({"SOURCE_DATE_EPOCH": "yesterday"})


@pytest.mark.parametrize("kw, msg", [
    (dict(version=0), "at least 1"),
    (dict(valid_s=0), "validity"),
    (dict(built_at_s=-1), "outside"),
])
def test_bad_release_is_refused(kw, msg):
    args = dict(version=1, built_at_s=BUILT_AT_S, valid_s=DAY) | kw
    with pytest.raises(BundleError, match=msg):
        Release(**args)


# --- the nightly job: no silent development key ---------------------------------------------------
def _job(tmp_path: Path, bundles: str) -> Path:
    from linedb import write_line_db

    write_line_db(tmp_path / "lines" / "tiny", nodes=None, edges=None)
    (tmp_path / "jobs").mkdir()
    p = tmp_path / "jobs" / "job.toml"
    p.write_text(f'[job]\nlines = ["lines/tiny"]\noutput_root = "out"\n[bundles]\n{bundles}\n')
    return p


def test_run_without_a_key_refuses_to_sign_with_a_development_key(tmp_path, monkeypatch):
    from planner.errors import JobError
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    monkeypatch.delenv("PLANNER_SIGNING_KEY", raising=False)
    job = _job(tmp_path, "")
    with pytest.raises(JobError, match="no signing key: set signing_key to a production key .* or "
                                       "allow_development_key = true"):
        run_job(load_job(job), show_progress=False)
    assert not (tmp_path / "out" / ".dev-key").exists() and not (tmp_path / "out" / "latest").exists()
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "PLANNER_SIGNING_KEY"}
    r = subprocess.run([sys.executable, "-m", "planner.cli", "run", str(job), "--no-progress"], env=env,
                       capture_output=True, text=True)
    lines = [x for x in (r.stdout + r.stderr).splitlines() if x.strip()]
    assert r.returncode != 0 and len(lines) == 1 and "allow_development_key" in lines[0], lines


def test_the_development_key_named_as_signing_key_still_needs_allowing(tmp_path, monkeypatch):
    from planner.errors import JobError
    from planner.job.config import load_job
    from planner.job.keys import signing_key_path

    monkeypatch.delenv("PLANNER_SIGNING_KEY", raising=False)
    signing.generate_keypair(tmp_path / "out" / ".dev-key")
    job = load_job(_job(tmp_path, 'signing_key = "out/.dev-key/signing_key.pem"'))
    with pytest.raises(JobError, match="is the development key"):
        signing_key_path(job, [])
    allowed = load_job(_job(tmp_path / "b", "allow_development_key = true"))
    notes: list[str] = []
    path, dev = signing_key_path(allowed, notes)
    assert dev and path.is_file() and "DEVELOPMENT key" in notes[0]


@pytest.mark.parametrize("now, due", [
    ("2026-01-01T00:00:00Z", False), ("2026-01-15T23:59:59Z", False), ("2026-01-16T00:00:00Z", True),
])
def test_an_unchanged_run_reissues_bundles_after_half_their_validity(now, due):
    from planner.job.pipeline import _renewal_due

    m = {"bundles_release": {"built_at": "2026-01-01T00:00:00Z", "expires": "2026-01-31T00:00:00Z"}}
    assert _renewal_due(m, parse_time(now)) is due
    assert _renewal_due({}, parse_time(now))  # a run from before releases: re-issue


def test_cli_build_stamps_version_expiry_and_key_kind(tmp_path):
    from linedb import write_line_db

    line_dir = write_line_db(tmp_path / "tiny", nodes=None, edges=None)
    priv, pub = signing.generate_keypair(tmp_path / "k")
    r = run_cli("bundle", "build", line_dir, "--out", tmp_path / "out", "--key", priv, "--train-type", "EMU6",
                "--direction", "up", "--built-at", "2026-11-23T04:00:00Z", "--valid-days", "2",
                "--bundle-version", "7", "--development-key")
    assert r.exit_code == 0, r.output
    assert "version 7, built 2026-11-23T04:00:00Z, expires 2026-11-25T04:00:00Z, development key" in r.output
    p = tmp_path / "out" / "tiny_up_EMU6.pdb"
    info = verify_bundle(p, pub, expect="tiny/up/EMU6", min_version=7, at="2026-11-24T00:00:00Z",
                         allow_dev=True)
    assert (info.bundle_version, info.key_kind) == (7, "development")
    r = run_cli("bundle", "build", line_dir, "--out", tmp_path / "out", "--key", priv, "--built-at", "yesterday")
    assert r.exit_code != 0 and "not an ISO 8601 time" in r.output


def test_run_overview_says_development_key_instead_of_failed(tmp_path, keys, small_line):
    """The run overview shows a development-signed bundle as verified but not for service (amber), a
    production one as verified, and a tampered one as FAILED."""
    import re

    from planner.pages.overview import _bundles

    run = tmp_path / "run"
    folder = run / "bundles"
    dev = build(small_line, folder, keys[0], development=True)
    prod = build(small_line, folder, keys[0], direction="up")
    shutil.copy(keys[1], folder / "signing_key.pub.pem")
    bad = folder / "tl_bad.pdb"
    data = bytearray(prod.read_bytes())
    data[600] ^= 1
    bad.write_bytes(bytes(data))
    status = {re.sub("<[^>]+>", "", row[0]): re.sub("<[^>]+>", "", row[1]) for row in _bundles(run)}
    assert status[dev.name].startswith("verified, development key: not for service")
    assert status[prod.name].startswith("verified (partial") and "development" not in status[prod.name]
    assert status[bad.name].startswith("FAILED")


@pytest.mark.parametrize("where", ["dev-key-folder", "marked-copy"])
def test_a_development_key_cannot_sign_production_bundles(tmp_path, where):
    """`bundle build --key` with the key `planner run` made for test runs (in its .dev-key folder, or copied
    elsewhere with its mark) refuses to stamp the bundles production; --development-key builds them."""
    import shutil

    from linedb import write_line_db

    line_dir = write_line_db(tmp_path / "tiny", nodes=None, edges=None)
    priv, _ = signing.generate_keypair(tmp_path / "outputs" / ".dev-key", development=True)
    if where == "marked-copy":
        shutil.copytree(priv.parent, tmp_path / "keys")
        priv = tmp_path / "keys" / priv.name
    assert signing.is_development_key(priv)
    args = ("bundle", "build", line_dir, "--out", tmp_path / "out", "--key", priv, "--train-type", "EMU6",
            "--direction", "up")
    r = run_cli(*args)
    err = r.output.strip()
    assert r.exit_code == 1 and err.startswith("error: --key") and "\n" not in err, r.output
    assert "development key" in err and "--development-key" in err and not list((tmp_path / "out").glob("*"))
    r = run_cli(*args, "--development-key")
    assert r.exit_code == 0 and "development key" in r.output, r.output


def test_a_production_key_beside_a_foreign_mark_is_not_development(tmp_path):
    """The mark names its key: a production key whose folder holds another key's mark stays production."""
    priv, _ = signing.generate_keypair(tmp_path / "k")
    (tmp_path / "k" / signing.DEV_MARKER_NAME).write_text("0" * 64 + "\n")
    assert not signing.is_development_key(priv)
