"""Physical verdicts on a leg: a flag that says what, under which conditions and where.

A train that stalls on a climb, or cannot stop where it must, is a verdict of physics about one
leg (interstation × direction × train type), not a failure of the run: the step that finds it
records a :class:`LegFlag` and computes everything else. The flags travel with the leg's results:
the tables (:class:`planner.tables.build.InterstationTables`, the ``table_a`` column
``ref_stall_position_m``), the closed loop (:class:`planner.tables.closed_loop.ClosedLoopResult`,
the ``closed_loop_summary`` columns ``flag_*``) and the margin report (an *unassessed* leg whose
``unassessed_cause``, ``unassessed_scenario`` and ``unassessed_position_m`` say why).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from planner.errors import StallError

STALL = "stall"
"""Kind of flag: the train cannot overcome resistance and gradient and comes to a stand."""
NO_STOP = "no_stop"
"""Kind of flag: no stopping pattern stops the train at the marker."""
KINDS = (STALL, NO_STOP)
NOMINAL = "nominal"
"""Scenario name of the tables' own train (load 0, nominal traction: the train the tables are for)."""
REFERENCE = "reference"
"""Scenario name of the reference train of tables (c) and (d) (full load, weak traction)."""


@dataclass(frozen=True)
class LegFlag:
    """A physical verdict on one leg.

    Attributes
    ----------
    kind : str
        :data:`STALL` or :data:`NO_STOP`.
    scenario : str
        Conditions it happens under: a closed-loop scenario name (``nominal``, ``perturbed``…),
        ``reference`` (the reference train of table (c)) or ``bad_day`` (the margin report's).
    position_m : float
        Chainage where it happens [m] (a stall: the end of the grid step where the speed
        reached zero); NaN when it is no place.
    reason : str
        One line for people: what, under which load and traction, where.
    """

    kind: str
    scenario: str
    position_m: float
    reason: str

    @classmethod
    def stall(cls, err: StallError, scenario: str) -> "LegFlag":
        """The flag of a :class:`StallError` raised under ``scenario``."""
        a, b = err.position_m
        return cls(STALL, scenario, float(b),
                   f"the train stalls ({scenario}: load {err.load:g}, traction ×{err.traction_factor:g}) "
                   f"between chainage {a:.0f} and {b:.0f} m")

    @classmethod
    def reference_stall(cls, ratio: float, position_m: float, load: float, traction_factor: float) -> "LegFlag":
        """The flag of a leg whose reference train (tables (c), (d)) stalls at constant ``ratio`` at
        ``position_m`` (the same words whether built or read back from ``table_a``)."""
        return cls(STALL, REFERENCE, float(position_m),
                   f"the reference train (load {load:g}, traction ×{traction_factor:g}) stalls at ratio "
                   f"{ratio:g} by chainage {position_m:.0f} m: no table (c) on this leg, so no adaptive mode")

    def __str__(self) -> str:
        return self.reason


def first(flags) -> LegFlag | None:
    """The first flag of a sequence (the one a single-valued column shows), or None."""
    return next(iter(flags), None)


def position_or_nan(flag: LegFlag | None) -> float:
    """``flag.position_m``, NaN without a flag."""
    return math.nan if flag is None else float(flag.position_m)


def flagged_legs(*results) -> dict[tuple[str, str, str, str], LegFlag]:
    """The first flag of each flagged leg among results of any step (tables, closed loop, margin legs).

    Each result has ``train_type, direction, origin, destination`` and ``flags``; the key is
    ``(train_type, direction, origin, destination)``, the flag the first one found in argument order.
    """
    out: dict[tuple[str, str, str, str], LegFlag] = {}
    for group in results:
        for r in group:
            if r.flags:
                out.setdefault((r.train_type, r.direction, r.origin, r.destination), r.flags[0])
    return out


@dataclass(frozen=True)
class FlaggedLeg:
    """A leg and its flags, for :func:`flagged_legs`, where a step's own result is not one (an approach whose
    stopping patterns are missing at some adhesion level: :func:`planner.stopping.sweep.no_stop_leg`)."""

    train_type: str
    direction: str
    origin: str
    destination: str
    flags: tuple[LegFlag, ...]

