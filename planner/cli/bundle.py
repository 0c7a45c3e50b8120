"""``planner keys generate`` and ``planner bundle build|verify``: signed on-board DB bundles."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..errors import PlannerError
from ..signing import ENV_SIGNING_KEY
from . import app

keys_app = typer.Typer(help="Ed25519 signing keys for on-board DB bundles.", no_args_is_help=True)
bundle_app = typer.Typer(help="Build and verify signed on-board DB bundles.", no_args_is_help=True)
app.add_typer(keys_app, name="keys")
app.add_typer(bundle_app, name="bundle")


def _fail(e: PlannerError) -> typer.Exit:
    typer.echo(f"error: {e}", err=True)
    return typer.Exit(e.exit_code)


@keys_app.command("generate")
def keys_generate(
    directory: Path = typer.Argument(..., help="Folder for signing_key.pem (mode 0600) and signing_key.pub.pem."),
) -> None:
    """Write a new Ed25519 key pair; never overwrites an existing key."""
    from ..signing import generate_keypair
    from .checks import check_out_dir

    try:
        check_out_dir(directory, "keys generate", "key pair")
        priv, pub = generate_keypair(directory)
    except PlannerError as e:
        raise _fail(e)
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
) -> None:
    """Build one signed bundle per direction x train type of a line."""
    from rich.progress import Progress

    from ..bundle import build_line
    from ..loader import load_line

    from .checks import check_out_dir, train_type_codes

    try:
        check_out_dir(out, "--out", "bundles")
        if key is None:
            raise PlannerError(f"no signing key: give --key FILE or set {ENV_SIGNING_KEY} to its path")
        line = load_line(line_dir)
        train_type = train_type_codes(line, train_type)
        n = len(direction or ("down", "up")) * len(train_type or line.train_types)
        with Progress(transient=True) as progress:
            task = progress.add_task("building bundles", total=n)
            infos = build_line(line, out, key, tables_dir=tables, stops_dir=stops, directions=direction,
                               train_types=train_type, on_built=lambda _: progress.advance(task))
    except PlannerError as e:
        raise _fail(e)
    for info in infos:
        state = "complete" if info.complete else "PARTIAL, missing " + ", ".join(info.missing)
        typer.echo(f"{info.path}: {info.size_bytes} bytes, {len(info.files)} tables, {state}")


def rebuild_advice(missing) -> str:
    """What fixes exactly these missing tables: the build option whose folder provides each."""
    from ..bundle import TABLE_SOURCES

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
    public_key: Path = typer.Option(..., "--public-key", help="Signer's public key (PEM)."),
    require_complete: bool = typer.Option(False, "--require-complete",
                                          help="Also fail when expected tables are missing."),
) -> None:
    """Check signature, hashes, schema and consistency; print what the bundle holds."""
    from ..bundle import verify_bundle
    from ..errors import BundleError

    try:
        info = verify_bundle(bundle, public_key)
        if require_complete and not info.complete:
            raise BundleError(f"bundle {bundle}: incomplete, missing {', '.join(info.missing)}; "
                              + rebuild_advice(info.missing))
    except PlannerError as e:
        raise _fail(e)
    typer.echo("OK: signature, hashes, schema and consistency verified")
    for line in info.summary():
        typer.echo(line)
