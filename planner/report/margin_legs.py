"""The timetable as legs for the margin report, and the groups its rows are computed in.

A **leg** is a run of a timetabled train from one stop to its next stop
(:func:`timetable_legs`). The margin report has one row per leg × scheduled
running time × **the temporary restrictions lifted for its trains**: on an
operating day with a restriction in force for part of the day, the trains that
run a leg while it is lifted (:func:`planner.line.operating_day.leg_restrictions`,
the per-train rule; the run passes the map from :func:`planner.job.day.lifted_restrictions`)
are computed on the day's line without it (:func:`planner.line.daily.without_temporary`),
in a row of their own; every other train, and every leg on a day whose restrictions
are all whole-day, is computed on the day's line as before.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Sequence

from planner.errors import InputError
from planner.line.operating_day import TEMPORARY_KIND, without_temporary
from planner.line.model import DIRECTIONS, Line, per_line

Lifted = Mapping[tuple[str, int], tuple[str, ...]]
"""``(train_id, leg_seq)`` → ids of the day's temporary restrictions lifted while the train runs that leg."""


@dataclass(frozen=True)
class TrainLeg:
    """One run of a timetabled train from a stop to its next stop."""

    train_id: str
    train_type: str
    direction: str
    leg_seq: int
    origin: str
    destination: str
    departure_s: float
    arrival_s: float

    @property
    def scheduled_s(self) -> float:
        """Scheduled running time: arrival at the next stop − departure [s]."""
        return self.arrival_s - self.departure_s


@per_line
def timetable_legs(line: Line) -> tuple[TrainLeg, ...]:
    """Every stop-to-stop run of the timetable (passes are run through; first and last call are stops).

    Made once per line object (:func:`~planner.line.model.per_line`): the nightly job asks for the same line's legs
    in several steps (its closed loop's look-ups, the margins, the lifted restrictions), 1.3 s of the job process
    each on the 100x line.

    Raises
    ------
    InputError
        A leg without a departure or arrival time, or not later than its departure.
    """
    out = []
    for tr in line.trains:
        calls = tr.stop_calls()
        for i, (a, b) in enumerate(zip(calls[:-1], calls[1:])):
            leg = TrainLeg(tr.train_id, tr.train_type, tr.direction, i, a.station_id, b.station_id,
                           float(a.departure_s), float(b.arrival_s))
            if not (math.isfinite(leg.scheduled_s) and leg.scheduled_s > 0):
                raise InputError(
                    f"timetable.parquet train {tr.train_id} calls seq {a.seq}->{b.seq} "
                    f"({a.station_id}->{b.station_id}): needs a departure and a later arrival "
                    f"(found departure_s={a.departure_s}, arrival_s={b.arrival_s})")
            out.append(leg)
    return tuple(out)


def lifted_of(leg: TrainLeg, lifted: Lifted | None) -> tuple[str, ...]:
    """The restrictions lifted while ``leg``'s train runs it (() for most)."""
    return tuple(lifted.get((leg.train_id, leg.leg_seq), ())) if lifted else ()


def scheduled_times(line: Line, types: Sequence[str], legs: Sequence[TrainLeg],
                    lifted: Lifted | None = None) -> dict[tuple, set]:
    """``{(direction, train_type, origin, destination, lifted ids): {scheduled times [s]}}``: every
    interstation of each type with nothing lifted (empty set: no train runs it) and every timetabled leg."""
    sched: dict[tuple, set] = {}
    for t in types:
        for d in DIRECTIONS:
            for a, b in line.interstations(d):
                sched.setdefault((d, t, a.station_id, b.station_id, ()), set())
    for lg in legs:
        sched.setdefault((lg.direction, lg.train_type, lg.origin, lg.destination, lifted_of(lg, lifted)),
                         set()).add(lg.scheduled_s)
    return sched


def group_window(line: Line, key: tuple) -> Line:
    """The slice of the line the group ``key`` (of :func:`scheduled_times`) is computed on: the leg's
    :meth:`Line.window` of the day's line without the group's lifted restrictions."""
    return without_temporary(line, key[4]).window(key[2], key[3], key[1])


def applied_restrictions(window: Line, direction: str, train_type: str) -> tuple[str, ...]:
    """Ids of the temporary restrictions a leg's slice (:func:`group_window`) holds for its direction and
    train type: those its trains are computed with (the ``restrictions`` column)."""
    return tuple(s.restriction_id for s in window.speed_limits
                 if s.kind == TEMPORARY_KIND and s.applies(direction, train_type))


def looked_up(sched: dict) -> list[float]:
    """The running times the legs look the closed loop's errors up at (``known_errors``): the scheduled times of
    the legs with nothing lifted (``sched``: :func:`scheduled_times`)."""
    return [t for k, v in sched.items() if not k[4] for t in v]


def looked_up_by_leg(line: Line, types: Sequence[str], lifted: Lifted | None = None) -> dict[tuple, list[float]]:
    """What :func:`planner.report.margins.compute_margins` of ``line`` looks the closed loop's errors up at, by leg:
    ``{(direction, train_type, origin, destination): [times, s]}``, sorted, the legs with none left out (the
    scheduled times of the legs with nothing lifted, :func:`looked_up`). What the margins look up of a leg's
    closed loop is at its own times only, so what a leg keeps of it
    (:class:`planner.report.margin_datasets.ClosedLoopFacts`) changes only when they do."""
    legs = [lg for lg in timetable_legs(line) if lg.train_type in types]
    out: dict[tuple, set] = {}
    for k, v in scheduled_times(line, types, legs, lifted).items():
        if not k[4] and v:
            out.setdefault(k[:4], set()).update(v)
    return {k: sorted(v) for k, v in out.items()}


__all__ = ["Lifted", "TrainLeg", "applied_restrictions", "group_window", "lifted_of", "looked_up", "looked_up_by_leg",
           "scheduled_times", "timetable_legs"]
