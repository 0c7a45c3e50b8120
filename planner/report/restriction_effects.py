"""What a day's temporary restrictions do to running times: the time each costs per interstation, the
scheduled legs they reach with their minimum and margin with and without them, and their share of the
impossible legs. The "restrictions in force" page (:mod:`planner.pages.restrictions`) and the changes against
the previous operating day (:mod:`planner.report.day_changes`) show these; the physics is the one integrator
(:func:`planner.physics.run_curve.simulate`) on the leg's :meth:`Line.window`.

The day's line is the static line plus the temporary restrictions (kind ``temporary``,
:func:`planner.job.day.day_line`); the static line is the same without them
(:func:`planner.line.operating_day.without_temporary`).
"""
from __future__ import annotations

import math
from typing import Sequence

from planner.line.operating_day import TEMPORARY_KIND, without_temporary


def _temporary(line) -> list:
    return [s for s in line.speed_limits if s.kind == TEMPORARY_KIND]


def _without(line, keep: Sequence[str] = ()):
    """``line`` without its temporary restrictions, except those whose id is in ``keep``."""
    return without_temporary(line, [s.restriction_id for s in _temporary(line) if s.restriction_id not in keep])


def min_time_s(line, train_type: str, origin: str, destination: str, ds_m: float = 1.0) -> float:
    """Minimum running time [s]: ratio 1.0, load 0, nominal traction (table (a) at ratio 1.0)."""
    from planner.physics.run_curve import simulate
    from planner.physics.track import SimSettings, make_track

    w = line.window(origin, destination, train_type)
    track = make_track(w, train_type, origin, destination, settings=SimSettings(ds_m=ds_m))
    return float(simulate(track, w.train_type(train_type), 1.0).time_s[0])


def reaches_leg(line, sl, train_type: str, direction: str, origin: str, destination: str) -> bool:
    """Whether speed limit ``sl`` concerns a run origin → destination of ``train_type`` (its window)."""
    lo, hi = line.window_m(origin, destination, train_type)
    return sl.applies(direction, train_type) and sl.end_m > lo and sl.start_m < hi


def restriction_losses(line, ds_m: float = 1.0) -> dict[str, list[tuple[str, str, str, str, float]]]:
    """Per temporary restriction id: (train type, direction, origin, destination, time lost [s]) on every
    interstation it reaches, with that restriction alone against the static line."""
    static = _without(line)
    temps = _temporary(line)
    out: dict[str, list] = {s.restriction_id: [] for s in temps}
    for tt in (t.train_type for t in line.train_types):
        for d in ("down", "up"):
            for a, b in line.interstations(d):
                hit = [s for s in temps if reaches_leg(line, s, tt, d, a.station_id, b.station_id)]
                if not hit:
                    continue
                base = min_time_s(static, tt, a.station_id, b.station_id, ds_m)
                for s in hit:
                    t = min_time_s(_without(line, (s.restriction_id,)), tt, a.station_id, b.station_id, ds_m)
                    out[s.restriction_id].append((tt, d, a.station_id, b.station_id, t - base))
    return out


def scheduled_legs(line, rows, ds_m: float = 1.0) -> list[dict]:
    """The margin report's rows (a DataFrame) whose leg a temporary restriction of the day reaches, with the
    minimum without them and the margin it had.

    Each row is computed with the restrictions that apply to its trains by the time they pass (its
    ``restrictions`` column, :func:`planner.line.operating_day.leg_restrictions`); those of the leg's
    restrictions not in it were lifted while the row's trains ran the leg (``lifted``): the row's minimum
    is the static line's there. Rows of a run before that column (None) had every restriction applied."""
    temps = _temporary(line)
    static = _without(line)
    out, cache = [], {}
    if rows is None or not len(rows) or not temps:
        return out
    for r in rows.to_dict("records"):
        sched = r.get("scheduled_running_time_s")
        if sched is None or (isinstance(sched, float) and math.isnan(sched)):
            continue
        k = (r["train_type"], r["direction"], r["origin"], r["destination"])
        reach = [s.restriction_id for s in temps if reaches_leg(line, s, *k)]
        if not reach:
            continue
        got = r.get("restrictions")
        ids = reach if got is None else [str(x) for x in got]
        if (k, tuple(ids)) not in cache:
            cache[(k, tuple(ids))] = (min_time_s(static, k[0], k[2], k[3], ds_m),
                                      min_time_s(_without(line, ids), k[0], k[2], k[3], ds_m))
        before, after = cache[(k, tuple(ids))]
        out.append({**{c: r.get(c) for c in ("train_type", "direction", "origin", "destination", "n_trains",
                                             "remaining_margin_s", "arrival_error_s", "arrival_error_degraded_s",
                                             "impossible", "short_bad_day", "tight", "unassessed",
                                             "unassessed_cause", "unassessed_reason")},
                    "train_ids": [] if r.get("train_ids") is None else list(r["train_ids"]), "restrictions": ids,
                    "lifted": [x for x in reach if x not in ids], "scheduled_s": float(sched),
                    "min_before_s": before, "min_after_s": after, "margin_before_s": float(sched) - before,
                    "margin_after_s": float(sched) - after})
    out.sort(key=lambda x: (x["margin_after_s"] >= 0, x["margin_after_s"]))
    return out


def effect(legs: list[dict], rows) -> dict:
    """What the day's restrictions do to the impossible legs (the overview says it): the margin rows flagged
    impossible, those of them the restrictions reach that are possible without them, and their train runs."""
    mine = [x for x in legs if x.get("impossible") and x["margin_before_s"] >= 0]
    return {"impossible": int(rows["impossible"].sum()) if rows is not None and len(rows) else 0,
            "impossible_by_restrictions": len(mine),
            "train_runs_by_restrictions": sum(int(x["n_trains"] or 0) for x in mine)}


__all__ = ["effect", "min_time_s", "reaches_leg", "restriction_losses", "scheduled_legs"]
