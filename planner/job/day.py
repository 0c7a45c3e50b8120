"""The job's operating day: which day a run plans, its daily feeds, and what is in force that day.

``[day]`` of the job file (:class:`planner.job.config.DaySection`) names the day
(or leaves it to the clock: the next operating day in the line's time zone, read
once when the run starts, like ``run_date``), the hour days start at, the time
zone and each line's daily feed (:mod:`planner.line.daily`). ``planner run
--day`` overrides the day (:func:`with_day`).

The pipeline asks :func:`day_inputs` for a line's :class:`DayInputs` (the
window, the restrictions in force, the trains that run) and puts
:func:`day_record` in the run's manifest; :func:`day_digest` goes into the
run's inputs digest (the day and the feeds' bytes), so another day or an edited
feed is another run.
"""
from __future__ import annotations

import dataclasses
from datetime import date, timedelta
from pathlib import Path

from planner.errors import InputError
from planner.job.config import Job
from planner.line.daily import load_feed
from planner.line.loader import source_digest
from planner.line.model import Line
from planner.line.operating_day import (
    DayInputs,
    leg_restrictions,
    next_operating_day,
    operating_day,
    restrictions_in_force,
    trains_running,
    whole_day,
    zone,
)

UTC_NAME = "UTC"


def time_zone(job: Job) -> str:
    """The job's time zone: ``[day] time_zone``, else UTC."""
    return job.day.time_zone or UTC_NAME


def _parse_day(text: str) -> date:
    if len(text) != 10:
        raise ValueError
    return date.fromisoformat(text)


def day_problems(job: Job) -> list[tuple[str, str]]:
    """``(key, message)`` for each bad ``[day]`` value (the job file's validation reports them with the others)."""
    out = []
    d = job.day
    if d.day:
        try:
            _parse_day(d.day)
        except ValueError:
            out.append(("day", f"expected a date YYYY-MM-DD (or \"\" for the next operating day), found {d.day!r}"))
    if not 0 <= d.start_hour <= 23:
        out.append(("start_hour", f"must be a whole hour 0..23, found {d.start_hour}"))
    if d.time_zone:
        try:
            zone(d.time_zone)
        except ValueError as e:
            out.append(("time_zone", str(e)))
    if d.feeds:
        feeds = []  # one message for the key: the job file's validation reports a key once
        if len(d.feeds) != len(job.job.lines):
            feeds.append(f"{len(d.feeds)} feed(s) for {len(job.job.lines)} line(s) of [job] lines; "
                         f"give one feed folder per line, in the same order")
        if not d.time_zone:
            out.append(("time_zone", "a daily feed's times are local: name the lines' time zone, e.g. "
                                     "\"Asia/Tokyo\""))
        for p in d.feeds:
            if not job.resolve(p).is_dir():
                feeds.append(f"daily feed folder {p!r} does not exist (resolved to {job.resolve(p)})")
        if feeds:
            out.append(("feeds", "; ".join(feeds)))
    return out


def with_day(job: Job, day: str) -> Job:
    """``job`` planning operating day ``day`` (YYYY-MM-DD): what ``planner run --day`` does."""
    try:
        _parse_day(day)
    except ValueError:
        raise InputError(f"--day: expected a date YYYY-MM-DD, found {day!r}") from None
    return dataclasses.replace(job, day=dataclasses.replace(job.day, day=day))


def resolve_day(job: Job, now_s: float | None = None) -> Job:
    """``job`` with its operating day fixed: ``[day] day``, else the next operating day in the job's time
    zone at ``now_s`` (default: the clock, read here once, at the start of the run)."""
    if job.day.day:
        return job
    if now_s is None:
        import time

        now_s = time.time()
    d = next_operating_day(now_s, time_zone(job), job.day.start_hour)
    return dataclasses.replace(job, day=dataclasses.replace(job.day, day=d.isoformat()))


def window(job: Job):
    """The :class:`~planner.line.operating_day.OperatingDay` of a job whose day is resolved."""
    if not job.day.day:
        raise InputError("the job's operating day is not resolved yet (resolve_day)")
    return operating_day(job.day.day, time_zone(job), job.day.start_hour)


def feed_of(job: Job, line: Line) -> str | None:
    """The daily feed folder of ``line`` as the job names it (matched by the line's folder in [job] lines),
    or None without feeds."""
    here = Path(line.source_path).resolve()
    for p, f in zip(job.job.lines, job.day.feeds):
        if job.resolve(p).resolve() == here:
            return f
    return None


def day_digest(job: Job) -> dict:
    """What the day adds to a run's inputs digest: the day, its hour and zone, each feed's bytes. A job
    whose day is not resolved yet is resolved by the clock, as :func:`resolve_day` does at the run's start
    (so the check before the workers start agrees with the run)."""
    job = resolve_day(job)
    return {"day": job.day.day, "start_hour": job.day.start_hour, "time_zone": time_zone(job),
            "feeds": [source_digest(job.resolve(f)) for f in job.day.feeds]}


def day_inputs(job: Job, line: Line) -> DayInputs:
    """What is in force on the job's operating day on ``line``: the window, the temporary restrictions in
    force at some instant of it, the timetable trains that run and those that do not.

    Raises ``LineValidationError`` (every broken rule of the feed, one line each) or ``InputError``.
    """
    return day_and_feed(job, line)[0]


def day_and_feed(job: Job, line: Line, w=None):
    """:func:`day_inputs` on window ``w`` (default: the job's day) and the line's loaded feed (None without)."""
    w = w or window(job)
    ids = [t.train_id for t in line.trains]
    name = feed_of(job, line)
    if name is None:  # a job without [day] feeds: the static line alone, every train every day
        return DayInputs(w, (), tuple(ids)), None
    path = job.resolve(name)
    feed = load_feed(path, line, time_zone(job))
    return _inputs_on(feed, line, w, name), feed


def _inputs_on(feed, line: Line, w, name: str) -> DayInputs:
    ids = [t.train_id for t in line.trains]
    running = trains_running(feed.calendar, w.day, ids)
    keep = set(running)
    notes = list(feed.notes)
    if ids and not running:
        notes.append(f"{line.line_id}: no train runs on {w.day} ({w.day:%A}) by the calendar of {name}: "
                     f"is a service missing for that day?")
    return DayInputs(w, restrictions_in_force(feed.restrictions, w), running,
                     tuple(t for t in ids if t not in keep), tuple(notes))


def day_changes(job: Job, line: Line, d: DayInputs, feed) -> dict | None:
    """The changes of ``line`` against the previous operating day (:func:`planner.report.day_changes.compare_days`)
    from the same feed, with each added, lifted or changed restriction's time lost (or regained) per leg and
    train type (:func:`planner.report.restriction_effects.restriction_losses`); None for a line without a feed."""
    from planner.report.restriction_effects import restriction_losses
    from planner.report.day_changes import calendar_covers, compare_days

    if feed is None:
        return None
    w = d.window
    prev = _inputs_on(feed, line, operating_day(w.day - timedelta(days=1), w.time_zone, w.start_hour),
                      feed_of(job, line))
    now_ids = {r.restriction_id: r for r in d.restrictions}
    was_ids = {r.restriction_id: r for r in prev.restrictions}

    def losses(rs, other):  # those not in force the same on the other day
        rs = [r for r in rs if other.get(r.restriction_id) != r]
        return restriction_losses(day_line(line, DayInputs(w, tuple(rs), ())), job.tables.ds_m) if rs else {}

    return compare_days(prev, d, line, feed.calendar.train_service if feed.calendar else None,
                        prev_covered=calendar_covers(feed.calendar, prev.window.day) or
                        not calendar_covers(feed.calendar, w.day),
                        losses_prev=losses(prev.restrictions, now_ids),
                        losses_today=losses(d.restrictions, was_ids))


def day_line(line: Line, d: DayInputs) -> Line:
    """``line`` as it is on the day: every temporary restriction in force at some instant of the day added to
    its speed limits (whole day, on the safe side: see docs/operating-day.md), and only the trains that run.
    Per train (margins, conflicts, train graph) the restrictions lifted while a train runs a leg are taken
    off again for that leg (:func:`lifted_restrictions`).

    Every unit is given a slice of this line (:meth:`Line.window`), so a unit's cache key (the digest of its
    slice) includes exactly the restrictions that reach it; the static line's ``source_digest`` is kept (it
    names the line database the run read), and :func:`line_digest` keys the line-level units.
    """
    keep = set(d.trains)
    return dataclasses.replace(
        line, speed_limits=line.speed_limits + tuple(r.as_speed_limit() for r in d.restrictions),
        trains=tuple(t for t in line.trains if t.train_id in keep))


def lifted_restrictions(line: Line, d: DayInputs) -> dict[tuple[str, int], tuple[str, ...]]:
    """Per train and leg of the day's line (``(train_id, leg_seq)``, the legs of
    :func:`planner.report.margin_legs.timetable_legs`): the ids of the day's temporary restrictions that
    reach the leg but do not apply to the train, lifted the whole time it runs the leg
    (:func:`~planner.line.operating_day.leg_restrictions`, the per-train rule), or that lie on a track
    (``track``) its route does not run on there. Only legs that have
    some; empty when every restriction of the day is in force for the whole day (nothing is looked at).

    Margins, conflicts and the train graph compute such a train's leg on the day's line without them,
    and their cache keys include this map: it is exactly what a train sees beyond the day's line.
    """
    from planner.report.margin_legs import timetable_legs

    w = d.window
    part = [r for r in d.restrictions if not whole_day(r, w) or r.track is not None]
    if not part:
        return {}
    users = _track_users(line, [r for r in part if r.track is not None])
    out = {}
    for lg in timetable_legs(line):
        key = (lg.train_type, lg.direction, lg.origin, lg.destination)
        near = leg_restrictions(part, w, line, *key)
        if not near:
            continue
        on = {r.restriction_id for r in leg_restrictions(near, w, line, *key, lg.departure_s, lg.arrival_s)
              if r.track is None or lg.train_id in users[r.restriction_id]}
        off = tuple(r.restriction_id for r in near if r.restriction_id not in on)
        if off:
            out[(lg.train_id, lg.leg_seq)] = off
    return out


def _track_users(line: Line, on_tracks: list) -> dict[str, set[str]]:
    """Per restriction on a named track: the trains whose route runs on that track inside its stretch. A
    train the network cannot route is counted in (on the safe side: it keeps the restriction)."""
    if not on_tracks:
        return {}
    if line.network is None:  # validation refuses a track on a line without a network; nothing to look at
        return {r.restriction_id: {t.train_id for t in line.trains} for r in on_tracks}
    from planner.network.routes import TrackGraph, plan_routes, runs_on

    g = TrackGraph(line)
    unrouted: dict[str, str] = {}
    routes = plan_routes(line, g, unrouted=unrouted)
    return {r.restriction_id: set(unrouted) | {tid for tid, rt in routes.items()
                                               if runs_on(g, rt, r.track, r.start_m, r.end_m)}
            for r in on_tracks}


def restriction_blocks(line: Line, bday) -> list[tuple]:
    """The day's temporary restrictions on ``line`` (the day's line: :func:`day_line`) as time–location blocks for
    the train graph: ``(restriction_id, start_m, end_m, from_s, until_s, limit_kmh, direction)``, the validity
    (``bday``: :func:`bundle_day`) on the timetable's clock (s after midnight of the operating day, as the
    trains' times: :func:`~planner.line.operating_day.timetable_instant`) clipped to the day's window. Empty
    without a daily feed."""
    from planner.line.daily import TEMPORARY_KIND
    from planner.line.operating_day import timetable_instant
    from planner.line.units import kmh

    if bday is None:
        return []
    base = timetable_instant(date.fromisoformat(bday.day), bday.time_zone, 0.0)
    valid = {rid: (a, b) for rid, a, b in bday.restrictions}
    return [(s.restriction_id, s.start_m, s.end_m, max(valid[s.restriction_id][0], bday.start_s) - base,
             min(valid[s.restriction_id][1], bday.end_s) - base, round(kmh(s.limit_ms), 9), s.direction)
            for s in line.speed_limits if s.kind == TEMPORARY_KIND and s.restriction_id in valid]


def line_on_day(job: Job, line: Line) -> tuple[Line, str, dict]:
    """``line`` as the nightly job plans it on the job's operating day (:func:`day_line` of :func:`day_inputs`:
    the day's temporary restrictions in force at some instant of the day, whole day, and the trains that run),
    one sentence saying so, and the restrictions lifted per train (:func:`lifted_restrictions`: what the
    night's per-train units, the conflict check among them, use beyond the day's line); for the one-off
    commands' ``--job`` (their answers are then the night's).

    Raises InputError when the job does not plan this line."""
    here = Path(line.source_path).resolve()
    if not any(job.resolve(p).resolve() == here for p in job.job.lines):
        raise InputError(f"--job: the job does not plan {line.source_path} ([job] lines: "
                         f"{', '.join(job.job.lines)}); give the job of this line, or leave --job out")
    d = day_inputs(job, line)
    ids = ", ".join(r.restriction_id for r in d.restrictions) or "none"
    on = day_line(line, d)
    return on, (f"operating day {d.window.day.isoformat()} of the job: temporary restrictions in force ({ids}) for the "
                f"whole day, as the tables and bundles count them; {len(d.trains)} of {len(line.trains)} trains "
                "run"), lifted_restrictions(on, d)


def lifted_key(lifted: dict) -> list:
    """The lifted map as plain, ordered data for a cache key."""
    return sorted([tid, seq, list(ids)] for (tid, seq), ids in lifted.items())


def line_digest(line: Line) -> str:
    """Key of what a line-level unit (margins, conflicts, train graph) sees of a :func:`day_line`: the static
    line, the temporary restrictions added and the trains that run."""
    from planner.job.publish import digest
    from planner.line.daily import TEMPORARY_KIND

    return digest([line.source_digest,
                   [dataclasses.astuple(s) for s in line.speed_limits if s.kind == TEMPORARY_KIND],
                   [t.train_id for t in line.trains]])


def bundle_day(job: Job, line: Line, d: DayInputs):
    """The :class:`~planner.bundle.manifest.BundleDay` of ``line``'s bundles: the day's window and the
    temporary restrictions in force with theirs; None for a line without a daily feed (its bundles are not
    bound to one day: nothing in them changes with the day)."""
    from planner.bundle.manifest import BundleDay

    if feed_of(job, line) is None:
        return None
    w = d.window
    return BundleDay(w.day.isoformat(), w.time_zone, w.start_s, w.end_s,
                     tuple((r.restriction_id, r.valid_from_s, r.valid_until_s) for r in d.restrictions))


def plan_day(job: Job, lines: list[Line], notes: list[str]) -> tuple[dict, list[Line], list, list[dict]]:
    """:func:`day_record` (with each line's changes against the previous day: :func:`day_changes`), each line
    as it is on the day (:func:`day_line`: what the run computes with), its bundles' day (:func:`bundle_day`)
    and the restrictions lifted per train (:func:`lifted_restrictions`)."""
    both = [day_and_feed(job, line) for line in lines]
    ins = [d for d, _ in both]
    rec = day_record(job, lines, notes, ins)
    for r, line, (d, feed) in zip(rec["lines"], lines, both):
        if feed is not None:
            r["changes"] = day_changes(job, line, d, feed)
    days = [day_line(ln, d) for ln, d in zip(lines, ins)]
    return (rec, days, [bundle_day(job, ln, d) for ln, d in zip(lines, ins)],
            [lifted_restrictions(ln, d) for ln, d in zip(days, ins)])


def day_record(job: Job, lines: list[Line], notes: list[str], ins: list[DayInputs] | None = None) -> dict:
    """The operating day for the run's manifest: window, and per line its feed, the restrictions in force
    and the trains that do not run; the day's notes are appended to ``notes``. Validates every feed, so a
    bad feed fails the run before anything is computed."""
    rec = window(job).record()
    rec["lines"] = []
    for i, line in enumerate(lines):
        d = ins[i] if ins is not None else day_inputs(job, line)
        notes.extend(d.notes)
        f = feed_of(job, line)
        rec["lines"].append({"line_id": line.line_id, "feed": Path(f).as_posix() if f else None,
                             "feed_digest": source_digest(job.resolve(f)) if f else None, **d.record()})
    return rec


__all__ = ["bundle_day", "day_and_feed", "day_changes", "day_digest", "day_inputs", "day_line", "day_problems",
           "day_record", "feed_of", "line_on_day", "lifted_key", "lifted_restrictions", "restriction_blocks", "line_digest", "plan_day", "resolve_day",
           "time_zone", "window", "with_day"]
