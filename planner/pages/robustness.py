"""Placeholder of the page ``report/<line>_robustness.html`` (the full page lands next): the summary only."""
from __future__ import annotations

import html


def write_page(path, line_name, summary, trains, stations, activities, events, *, nav=""):
    from planner.io.atomic import write_bytes_atomic

    body = "".join(f"<li>{html.escape(str(k))}: {html.escape(str(v))}</li>" for k, v in sorted(summary.items()))
    write_bytes_atomic(path, f"<!DOCTYPE html><html><body>{nav}<h1>{html.escape(line_name)}</h1><ul>{body}</ul>"
                             "</body></html>".encode())
    return path
