"""``planner keys generate`` and ``planner bundle build|verify``: signed on-board DB bundles."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import BundleError, PlannerError
from planner.bundle.signing import ENV_SIGNING_KEY, is_development_key
from . import app

keys_app = typer.Typer(help="Ed25519 signing keys for on-board DB bundles.", no_args_is_help=True)
bundle_app = typer.Typer(help="Build and verify signed on-board DB bundles.", no_args_is_help=True)
app.add_typer(keys_app, name="keys")
app.add_typer(bundle_app, name="bundle")


@keys_app.command("generate")
def keys_generate(
    directory: Path = typer.Argument(..., help="Folder for signing_key.pem (mode 0600) and signing_key.pub.pem."),
) -> None:
    """Write a new Ed25519 key pair; never overwrites an existing key."""
    from planner.bundle.signing import generate_keypair
    from .checks import check_out_dir

    check_out_dir(directory, "keys generate", "key pair")
    priv, pub = generate_keypair(directory)
    typer.echo(f"private key: {priv} (keep it secret; mode 0600)")
    typer.echo(f"public key:  {pub} (give it to the vehicles)")


@bundle_app.command("build")
def bundle_build(
    line_dir: Path = typer.Argument(..., help="Line database folder."),
    out: Path = typer.Option(..., "--out", help="Folder the bundles are written to."),
    key: Optional[Path] = typer.Option(
        None, "--key", envvar=ENV_SIGNING_KEY, show_envvar=True,
        help="Private signing key file (PEM). Never copied into the output."),
    tables: Optional[Path] = typer.Option(None, "--tables", help="Output folder of `planner tables`."),
    stops: Optional[Path] = typer.Option(None, "--stops", help="Output folder of the stopping-pattern step."),
    direction: Optional[list[str]] = typer.Option(None, "--direction", help="down or up (repeatable; default both)."),
    train_type: Optional[list[str]] = typer.Option(None, "--train-type", help="Train type (repeatable; default all)."),
    built_at: Optional[str] = typer.Option(
        None, "--built-at", help="Build time, ISO 8601 (e.g. 2026-11-23T04:00:00Z). Default: $SOURCE_DATE_EPOCH, "
                                 "else now. Same inputs + same build time = same bytes."),
    bundle_version: Optional[int] = typer.Option(
        None, "--bundle-version", min=1,
        help="Bundle version (default: the build time as YYYYMMDDHHMMSS, which grows with every build)."),
    valid_days: float = typer.Option(30.0, "--valid-days", help="Days after the build time the bundle expires."),
    development_key: bool = typer.Option(
        False, "--development-key", help="Mark the bundles as signed with a development key (not for service)."),
) -> None:
    """Build one signed bundle per direction x train type of a line."""
    from .progress import bar as progress_bar

    from planner.bundle.container import build_line
    from planner.bundle.manifest import Release, parse_time
    from planner.line.loader import load_line

    from .checks import check_out_dir, train_type_codes

    check_out_dir(out, "--out", "bundles")
    if key is None:
        raise PlannerError(f"no signing key: give --key FILE or set {ENV_SIGNING_KEY} to its path")
    if not development_key and is_development_key(key):
        raise PlannerError(f"--key {key}: a development key (made for test runs) cannot sign bundles for service; "
                           "sign with a production key (`planner keys generate DIR`), or pass --development-key "
                           "to mark the bundles development")
    release = Release.issue(None if built_at is None else parse_time(built_at, "--built-at"),
                            valid_days=valid_days, development=development_key, version=bundle_version)
    line = load_line(line_dir)
    train_type = train_type_codes(line, train_type)
    n = len(direction or ("down", "up")) * len(train_type or line.train_types)
    with progress_bar() as progress:
        task = progress.add_task("building bundles", total=n)
        try:
            infos = build_line(line, out, key, release=release, tables_dir=tables, stops_dir=stops,
                               directions=direction,
                               train_types=train_type, on_built=lambda _: progress.advance(task))
        except OSError as e:  # a bundle cannot be written (the key and the line were read before)
            raise BundleError(f"cannot write {e.filename or out}: {e.strerror or e}; check --out (space, "
                              "permissions)") from None
    for info in infos:
        state = "complete" if info.complete else "PARTIAL: " + info.incomplete_text()
        typer.echo(f"{info.path}: {info.size_bytes} bytes, {len(info.files)} tables, {state}")
    if infos:
        i = infos[0]
        typer.echo(f"version {i.bundle_version}, built {i.built_at}, expires {i.expires}, {i.key_kind} key")


def rebuild_advice(missing) -> str:
    """What fixes exactly these missing tables: the build option whose folder provides each."""
    from planner.bundle.assemble import TABLE_SOURCES

    step = {"tables": "`planner tables LINE --out DIR`", "stops": "`planner stops LINE --out DIR`"}
    parts = []
    for opt, names in TABLE_SOURCES.items():
        mine = [t for t in missing if t in names]
        if mine:
            parts.append(f"--{opt} DIR with a folder written by {step[opt]} that holds {', '.join(mine)}")
    return "rebuild it with `planner bundle build` and " + "; and ".join(parts)


@bundle_app.command("verify")
def bundle_verify(
    bundle: Path = typer.Argument(..., help="Bundle file (.pdb)."),
    public_key: Path = typer.Option(..., "--public-key", help="Signer's public key (PEM): the one the vehicle trusts."),
    expect: str = typer.Option(..., "--expect",
                               help="LINE/DIRECTION/TYPE the bundle must be for, e.g. sample/down/E10."),
    min_version: int = typer.Option(0, "--min-version", min=0,
                                    help="Refuse a bundle version below this (the installed version: rollback)."),
    at: Optional[str] = typer.Option(None, "--at", help="Time of the expiry and operating-day checks, ISO 8601 "
                                                        "(default now); without an offset, the local time of the "
                                                        "bundle's operating day (its time zone), e.g. "
                                                        "2026-11-30T12:00; a bundle bound to no day takes it as UTC."),
    allow_dev: bool = typer.Option(False, "--allow-dev", help="Accept a bundle signed with a development key."),
    require_complete: bool = typer.Option(False, "--require-complete",
                                          help="Also fail when expected tables are missing or a stop has no "
                                               "stopping pattern at some adhesion level."),
) -> None:
    """Check signature, key id, target, key kind, version, expiry, hashes, schema and consistency."""
    from planner.bundle.verify import verify_bundle

    info = verify_bundle(bundle, public_key, expect=expect, min_version=min_version, at=at,
                         allow_dev=allow_dev)
    if require_complete and info.missing:
        raise BundleError(f"bundle {bundle}: incomplete, {info.incomplete_text()}; " + rebuild_advice(info.missing))
    if require_complete and info.no_stop:
        raise BundleError(f"bundle {bundle}: incomplete, {info.incomplete_text()}: it cannot stop its train there at "
                          "those adhesion levels; change what makes the stop impossible (a restriction ahead of the "
                          "stop, the approach) and rebuild, or load it knowingly without --require-complete")
    typer.echo(f"OK: {info.target} version {info.bundle_version}: signature, key id, target, freshness, hashes, "
               "schema and consistency verified")
    for line in info.summary():
        typer.echo(line)
