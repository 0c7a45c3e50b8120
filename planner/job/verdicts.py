"""The run's physical verdicts: legs where a train stalls or cannot stop, as flags and notes of the run.

A verdict of physics on one leg (:mod:`planner.tables.flags`) never fails the night: the steps
record it on the leg and compute everything else. Here the run gathers them from the tables, the
closed loop and the margin report into the manifest's ``flags`` (``stalls``, ``no_stop``: legs,
each counted once) and one note per flagged leg, which the run overview shows as flag cards.
"""
from __future__ import annotations

from planner.tables.flags import KINDS, LegFlag, flagged_legs


def record_verdicts(line_id: str, summary, tables, stops, loops, report) -> None:
    """Add the legs flagged by any step (``stops``: the legs with no stopping pattern at some adhesion level,
    :func:`planner.stopping.sweep.no_stop_leg`) to ``summary.flags`` and ``summary.notes`` (one note per leg)."""
    found = flagged_legs(tables, stops, loops)
    rows = report.rows
    if len(rows) and "unassessed_cause" in rows:
        for r in rows[rows["unassessed_cause"].astype(str) != ""].itertuples(index=False):
            found.setdefault((r.train_type, r.direction, r.origin, r.destination),
                             LegFlag(r.unassessed_cause, r.unassessed_scenario, float(r.unassessed_position_m),
                                     str(r.unassessed_reason)))
    for kind in KINDS:
        key = "stalls" if kind == "stall" else kind
        summary.flags[key] = summary.flags.get(key, 0) + sum(f.kind == kind for f in found.values())
    for (tt, d, o, de), f in sorted(found.items()):
        summary.notes.append(f"{line_id}: {tt} {d} {o}->{de}: {f.reason}")
