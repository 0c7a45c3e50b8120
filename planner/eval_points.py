"""Evaluation points: where the on-board logic re-evaluates the remaining time (DESIGN §3).

Per interstation and direction the points are, in running order:

* ``dep`` — the departure (running distance 0, the origin's stop marker);
* ``dep+200`` — a point shortly after departure (200 m by default,
  configurable; left out when the interstation is not longer than that);
* every beacon read in that direction and flagged ``evaluation_point``,
  strictly between the two stations' stop markers, under its ``beacon_id``.

Positions are given twice: ``s_m``, the running distance from the departure
stop marker (what the simulator integrates over), and ``position_m``, the
chainage (what the line database and the vehicle's beacon list use):
``position_m = stop_origin + sign(direction) · s_m``.

Two points at the same running distance would be the same decision twice; the
later one in the order above is dropped (a beacon exactly 200 m after the
departure replaces nothing and is not listed twice). The points do not depend
on the train type; the datasets still carry it because tables are per type.
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import InputError
from .model import Line, sign

DEFAULT_AFTER_DEPARTURE_M = 200.0
"""Default distance of the point after departure [m] (DESIGN §3)."""
SAME_POINT_M = 1e-6
"""Points closer than this [m] are one point (far below any grid step)."""


@dataclass(frozen=True)
class EvalPoint:
    """One evaluation point of an interstation in one direction.

    Attributes
    ----------
    eval_point_id : str
        ``dep``, ``dep+<metres>`` or the beacon id.
    s_m : float
        Running distance from the departure stop marker [m], 0 ≤ s < length.
    position_m : float
        Chainage [m].
    """

    eval_point_id: str
    s_m: float
    position_m: float


def interstation_length_m(line: Line, origin: str, destination: str) -> float:
    """Running distance from the origin's stop marker to the destination's [m]."""
    return line.run_between(origin, destination).length_m


def evaluation_points(
    line: Line,
    origin: str,
    destination: str,
    *,
    after_departure_m: float | None = DEFAULT_AFTER_DEPARTURE_M,
) -> tuple[EvalPoint, ...]:
    """Evaluation points of one interstation, in running order.

    Parameters
    ----------
    line : Line
        The line.
    origin, destination : str
        Station ids; the direction follows from their chainages.
    after_departure_m : float or None
        Distance of the point after departure [m]; None or 0 leaves it out.

    Returns
    -------
    tuple of EvalPoint
        Sorted by ``s_m``; the first is always ``dep`` at s = 0.

    Raises
    ------
    InputError
        A negative ``after_departure_m``, or an interstation whose stop markers
        do not follow the running direction.

    Examples
    --------
    >>> from planner import testing
    >>> [p.eval_point_id for p in evaluation_points(testing.line(), "S0", "S1")]
    ['dep', 'dep+200']
    """
    d = line.direction_between(origin, destination)
    sg = sign(d)
    stop0 = line.station(origin).stop_m(d)
    length = interstation_length_m(line, origin, destination)
    if not length > 0:
        raise InputError(
            f"interstation {origin}->{destination} ({d}): stop markers do not follow the running direction "
            f"(length {length:.1f} m); fix stop_{d}_m in stations.parquet"
        )
    pts = [EvalPoint("dep", 0.0, stop0)]
    if after_departure_m is not None and after_departure_m != 0:
        if after_departure_m < 0:
            raise InputError(f"--after-departure must be >= 0 m, got {after_departure_m}")
        if after_departure_m < length:
            pts.append(EvalPoint(f"dep+{after_departure_m:g}", float(after_departure_m),
                                 stop0 + sg * float(after_departure_m)))
    for b in line.beacons_for(d):
        if not b.evaluation_point:
            continue
        s = sg * (b.position_m - stop0)
        if 0.0 < s < length:
            pts.append(EvalPoint(b.beacon_id, float(s), float(b.position_m)))
    pts.sort(key=lambda p: p.s_m)  # stable: dep+200 before a beacon at the same place
    out: list[EvalPoint] = []
    for p in pts:
        if out and p.s_m - out[-1].s_m < SAME_POINT_M:
            continue
        out.append(p)
    return tuple(out)
