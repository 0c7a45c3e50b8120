"""`planner kernels build|status`: the compiled kernels' machine code, built once at install.

``make install`` runs ``planner kernels build``: the integrator's inner loop and the
stopping solver compiled ahead of time into extension modules under
``planner/_aot/`` (see :mod:`planner.io.compiled`), so no process compiles
them at run time. ``status`` says whether each is built for the current sources.
"""
from __future__ import annotations

import time

import typer

from . import app

kernels_app = typer.Typer(help="Build or inspect the compiled kernels (built once at install).",
                          no_args_is_help=True, rich_markup_mode=None)
app.add_typer(kernels_app, name="kernels")

_KINDS = ("integrator", "stopping", "delay")


def _sources(kind: str) -> tuple[str, ...]:
    if kind == "integrator":
        from planner.physics.kernel_abi import SOURCES
    elif kind == "delay":
        from planner.delay.propagate import SOURCES
    else:
        from planner.stopping.codes import SOURCES
    return SOURCES


@kernels_app.command("build")
def build(
    force: bool = typer.Option(False, "--force", help="Rebuild even where a build for these sources exists."),
) -> None:
    """Compile the integrator, the stopping solver and delay propagation into extension modules (about 20 s of CPU)."""
    from planner.io import compiled

    for kind in _KINDS:
        st = compiled.status(kind, _sources(kind), env=False)
        if st["state"] == "built" and not force:
            typer.echo(f"{kind}: up to date ({st['module']})")
            continue
        t0 = time.process_time()
        if kind == "integrator":
            from planner.physics.kernel import JIT
        elif kind == "delay":
            from planner.delay.kernel import JIT
        else:
            from planner.stopping.kernel import JIT
        try:
            path = compiled.build(kind, _sources(kind), JIT)
        except Exception as e:  # the compiler's own failure: one line, and the kernels still run just in time
            typer.echo(f"error: building the {kind} kernel failed ({type(e).__name__}: {e}); planner still works "
                       "but compiles it in every process", err=True)
            raise typer.Exit(1) from None
        typer.echo(f"{kind}: built {path.name} in {time.process_time() - t0:.1f} s of CPU")


@kernels_app.command("status")
def status() -> None:
    """Say, for each kernel, whether a process loads its build or compiles it just in time; exit 1 if any compiles."""
    from planner.io import compiled

    missing = 0
    for kind in _KINDS:
        st = compiled.status(kind, _sources(kind))
        typer.echo(f"{kind}: {st['state']}: {st['path']}")
        missing += st["state"] != "built"
    if missing:
        typer.echo("build them with: planner kernels build", err=True)
        raise typer.Exit(1)
