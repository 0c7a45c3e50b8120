"""What changed against the previous operating day: restrictions added, lifted and changed, trains added and
cancelled, with their effects (pure: plain data for the run manifest and the pages).

Both days come from the same daily feed (:class:`~planner.line.operating_day.DayInputs` of day D − 1 and
D): the comparison is of what the feed, as it stands tonight, puts in force on each day, so it needs no
second run. Restrictions are matched by id:

* **added**: in force on D, not on D − 1; **lifted**: in force on D − 1, not on D;
* **changed**: in force on both with another stretch, limit, direction, train type, validity or beacon
  (only when the two days' inputs come from different feed versions: one feed gives an id one row);
* **kept**: in force on both, the same; whether each covered the whole day or part of it is kept
  (a restriction that starts in the afternoon of D − 1 is part of D − 1, all of D).

Their effects are the minimum running times of :func:`planner.report.restriction_effects.restriction_losses`
(each restriction alone against the static line, per interstation it reaches and train type): the time
an added restriction costs, the time a lifted one gives back. The caller computes them (the one
integrator) and passes them in, so this module stays a pure comparison.

Trains are compared by id: added (run on D, not on D − 1), cancelled (the reverse), counted by service
and train type, with their stop-to-stop legs (:func:`planner.report.margins.timetable_legs`). When the
feed's calendar does not cover D − 1 (the first day of the feed: no service dates reach back to it) the
trains are not compared, and the record says so.
"""
from __future__ import annotations

import dataclasses
from collections import Counter
from datetime import date
from typing import Iterable, Mapping, Sequence

RESTRICTION_FIELDS = ("start_m", "end_m", "limit_kmh", "direction", "train_type", "valid_from", "valid_until",
                      "has_beacon")
"""The fields whose difference makes a restriction in force on both days *changed* (its reason does not)."""

Losses = Mapping[str, Sequence[tuple[str, str, str, str, float]]]
"""Restriction id → (train type, direction, origin, destination, time [s]) per interstation it reaches:
what :func:`planner.report.restriction_effects.restriction_losses` returns."""


def calendar_covers(calendar, day: date) -> bool:
    """Whether the feed's calendar says anything about ``day``: a service's date range holds it or a dated
    exception names it. Without a calendar every train runs every day, so every day is covered."""
    if calendar is None:
        return True
    return (any(s.start_date <= day <= s.end_date for s in calendar.services.values())
            or any(d == day for _, d in calendar.exceptions))


def _legs(losses: Losses | None, rid: str) -> list[dict]:
    return [{"train_type": tt, "direction": d, "origin": o, "destination": b, "time_s": round(float(t), 2)}
            for tt, d, o, b, t in (losses or {}).get(rid, ())]


def _trains(ids: Sequence[str], line, services: Mapping[str, str] | None) -> dict:
    """Trains ``ids`` (timetable order): their ids, their number per service and train type, their legs."""
    from planner.report.margins import timetable_legs

    keep = set(ids)
    trains = [t for t in line.trains if t.train_id in keep]
    by = Counter(((services or {}).get(t.train_id), t.train_type) for t in trains)
    legs = Counter((g.train_type, g.direction, g.origin, g.destination)
                   for g in timetable_legs(dataclasses.replace(line, trains=tuple(trains))))
    return {"count": len(ids), "train_ids": list(ids),
            "by_service": [{"service_id": s, "train_type": tt, "trains": n} for (s, tt), n in
                           sorted(by.items(), key=lambda x: (x[0][0] or "", x[0][1]))],
            "legs": [{"train_type": k[0], "direction": k[1], "origin": k[2], "destination": k[3], "trains": n}
                     for k, n in legs.items()]}


def compare_days(prev, today, line, services: Mapping[str, str] | None = None, *, prev_covered: bool = True,
                 losses_prev: Losses | None = None, losses_today: Losses | None = None) -> dict:
    """The changes from operating day ``prev`` to ``today`` (both :class:`DayInputs` of ``line``) as plain data.

    Parameters
    ----------
    prev, today : DayInputs
        What is in force on D − 1 and on D (the same feed).
    line : Line
        The static line (its timetable gives the trains' types and legs).
    services : mapping, optional
        Train id → service id (the feed's ``train_services``), to count trains per service.
    prev_covered : bool
        False when the feed's calendar does not reach back to D − 1 (:func:`calendar_covers`): the trains
        are not compared.
    losses_prev, losses_today : mapping, optional
        :data:`Losses` of the restrictions in force on D − 1 (for the lifted and the changed ones' old
        versions) and on D (the added and the changed ones' new versions).

    Returns
    -------
    dict
        ``previous_day``, ``previous_weekday``, ``restrictions_added`` / ``restrictions_lifted`` (each
        restriction's record with ``whole_day`` on its day and ``legs``: time lost, or regained, per train
        type and interstation), ``restrictions_changed`` (``fields`` that differ, ``before`` and ``after``),
        ``restrictions_kept`` (id, whole day before and after), ``trains_compared``, ``trains_added`` and
        ``trains_cancelled`` (``count``, ``train_ids``, ``by_service``, ``legs``) and ``note``.
    """
    wp, wt = prev.window, today.window
    before = {r.restriction_id: r for r in prev.restrictions}
    after = {r.restriction_id: r for r in today.restrictions}
    added, changed, kept = [], [], []
    for rid, r in after.items():
        old = before.get(rid)
        if old is None:
            added.append({**r.record(wt), "legs": _legs(losses_today, rid)})
            continue
        a, b = old.record(wp), r.record(wt)
        fields = [f for f in RESTRICTION_FIELDS if a[f] != b[f]]
        if fields:
            changed.append({"restriction_id": rid, "fields": fields, "before": a, "after": b,
                            "legs_before": _legs(losses_prev, rid), "legs_after": _legs(losses_today, rid)})
        else:
            kept.append({"restriction_id": rid, "whole_day_before": a["whole_day"], "whole_day_after": b["whole_day"]})
    lifted = [{**r.record(wp), "legs": _legs(losses_prev, rid)} for rid, r in before.items() if rid not in after]
    out = {"previous_day": wp.day.isoformat(), "previous_weekday": f"{wp.day:%A}",
           "restrictions_added": added, "restrictions_lifted": lifted, "restrictions_changed": changed,
           "restrictions_kept": kept, "trains_compared": bool(prev_covered), "note": ""}
    if prev_covered:
        was, now = set(prev.trains), set(today.trains)
        out["trains_added"] = _trains([t for t in today.trains if t not in was], line, services)
        out["trains_cancelled"] = _trains([t for t in prev.trains if t not in now], line, services)
    else:
        out["trains_added"] = out["trains_cancelled"] = None
        out["note"] = (f"the daily feed's calendar says nothing about {wp.day.isoformat()} (no service's dates "
                       f"and no exception reach it: the first day of the feed?), so the trains are not compared "
                       f"with the previous day")
    return out


def flagged_legs(changes: dict, rows, flags: Iterable[str]) -> list[dict]:
    """The margin report's rows (a DataFrame, or None) that an added train runs and that carry a flag: leg,
    worst flag, the added trains on it. Rows ``train_ids`` name every train of the leg at that scheduled
    time; only the added ones are listed."""
    added = set(((changes or {}).get("trains_added") or {}).get("train_ids") or ())
    if rows is None or not len(rows) or not added:
        return []
    flags = tuple(flags)
    out = []
    for r in rows.to_dict("records"):
        ids = [t for t in (r.get("train_ids") if r.get("train_ids") is not None else ()) if t in added]
        worst = next((f for f in flags if bool(r.get(f) or False)), None)
        if ids and worst is not None:
            out.append({"train_type": r["train_type"], "direction": r["direction"], "origin": r["origin"],
                        "destination": r["destination"], "flag": worst, "trains": ids})
    return out


def counts(changes: dict | None) -> dict[str, int]:
    """How many restrictions were added, lifted, changed and trains added, cancelled (0 when not compared)."""
    c = changes or {}
    return {"restrictions_added": len(c.get("restrictions_added") or ()),
            "restrictions_lifted": len(c.get("restrictions_lifted") or ()),
            "restrictions_changed": len(c.get("restrictions_changed") or ()),
            "trains_added": int((c.get("trains_added") or {}).get("count", 0)),
            "trains_cancelled": int((c.get("trains_cancelled") or {}).get("count", 0))}


__all__ = ["RESTRICTION_FIELDS", "calendar_covers", "compare_days", "counts", "flagged_legs"]
