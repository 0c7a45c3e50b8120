"""The commands' progress bars: on stderr and only on a terminal, so stdout holds the results alone.

A transient rich bar on a stdout that is not a terminal (a pipe, a file, a test runner) still
printed one empty line when it stopped: every command's output began with a blank line.
"""
from __future__ import annotations


def bar(*columns):
    """A transient ``rich.progress.Progress`` drawn on stderr, disabled when stderr is not a terminal."""
    from rich.console import Console
    from rich.progress import Progress

    console = Console(stderr=True)
    return Progress(*columns, transient=True, console=console, disable=not console.is_terminal)
