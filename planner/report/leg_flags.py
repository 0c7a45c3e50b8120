"""The flags of a leg in words: what each one means, its badge, its card, and what caused it (pure).

:func:`planner.report.margin_rule.margin_columns` decides the flags from plain
numbers; this module says them, once, for every page and dataset that shows
them (the margin report, the run overview, the CLI, the changes):

=================  ==========================================================================
flag               the leg ...
=================  ==========================================================================
``unassessed``     has no bad-day minimum (or no minimum): ``unassessed_reason`` says why
``impossible``     is scheduled below its minimum running time (ratio 100 %, empty, nominal
                   traction): no driving can make it, on any day
``short_bad_day``  meets the minimum but not the bad-day minimum: it runs late on a bad day,
                   by ``-remaining_margin_s``
``unreachable``    is scheduled above the slowest table time: the train arrives early
``inaccurate``     the closed loop misses the designated arrival by more than the threshold
``tight``          neither, but less than ``tight_threshold_s`` is left on a bad day
=================  ==========================================================================

``infeasible`` (impossible or short on the bad day) is kept in the ``margins``
dataset for the queries and runs from before the two were told apart; no page
shows it as a flag of its own.

The cause of a leg that is short on the bad day (or tight) is the largest of the
bad day's shares (:data:`CAUSES`), which add up to the bad-day cost (degraded −
minimum): ``load``, ``traction``, ``adhesion`` (the stop at the bad day's
adhesion) or ``stop_model`` (the stopping pattern against the tables' constant
stopping brake: no effect of the bad day, but of the model).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Flag:
    """One flag of a leg: its column, its badge text, its colour and its card's words."""

    name: str
    badge: str
    colour: str
    card: str
    severity: str  # card class: ``bad`` (the timetable cannot be kept), ``warn``, ``purple``


FLAGS_SHOWN = (
    Flag("unassessed", "unassessed", "#37474f", "legs unassessed: no bad-day minimum could be computed", "bad"),
    Flag("impossible", "impossible", "#7f0000", "legs impossible: scheduled below the minimum running time "
         "(no driving makes it)", "bad"),
    Flag("short_bad_day", "short on a bad day", "#d84315", "legs short on a bad day: they meet the minimum but "
         "not the bad-day minimum", "bad"),
    Flag("unreachable", "unreachable", "#6a1b9a", "legs unreachable: longer than the slowest ratio", "purple"),
    Flag("inaccurate", "inaccurate", "#8d6e00", "legs inaccurate: the closed loop misses the arrival by more "
         "than the threshold", "warn"),
    Flag("tight", "tight", "#ef8f00", "legs tight: little left on a bad day", "warn"),
)
"""The flags a page shows, worst first (the order of badges, cards and the row colour)."""

FLAG = {f.name: f for f in FLAGS_SHOWN}
FLAGS = tuple(f.name for f in FLAGS_SHOWN)
"""The flag columns of a leg, worst first."""

CAUSES = (("load", "degraded_loss_load_s"), ("traction", "degraded_loss_traction_s"),
          ("adhesion", "degraded_loss_stop_s"), ("stop_model", "degraded_loss_stop_model_s"))
"""The shares of the bad day's cost in the ``margins`` dataset, by the name a cause takes."""
CAUSE_WORDS = {"load": "the load", "traction": "the weak traction", "adhesion": "the stop at low adhesion",
               "stop_model": "the stop model (stopping pattern against the stopping brake)"}


def flag_of(r) -> str:
    """The worst flag of a margin row (``ok`` when it has none), for colours and badges."""
    for f in FLAGS:
        if _true(getattr(r, f, False)):
            return f
    return "ok"


def flags_of(r) -> list[str]:
    """Every flag of a margin row, worst first."""
    return [f for f in FLAGS if _true(getattr(r, f, False))]


def _true(v) -> bool:
    """A flag value as a truth: null (unknown) and NaN are not set."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return False
    try:
        return bool(v)
    except TypeError:  # pandas.NA
        return False


def added_up(total: float, parts, nd: int = 1) -> tuple[float, list[float]]:
    """``total`` and its ``parts`` rounded to ``nd`` decimals so that the rounded parts add up to the rounded total.

    Each part is rounded down to the unit, then the units the rounded total still lacks go to the
    parts with the largest remainders (the largest-remainder method), so a row never shows
    ``14.8 = 7.0 + 3.0 + 5.5 − 0.6`` off by a unit. The parts must add up to the total (to round-off).

    Examples
    --------
    >>> added_up(0.15, [0.05, 0.05, 0.05])
    (0.1, [0.1, 0.0, 0.0])
    >>> added_up(14.830341, [6.953380, 2.989338, 5.464473, -0.576850])
    (14.8, [6.9, 3.0, 5.5, -0.6])
    """
    unit = 10.0 ** -nd
    t = round(float(f"{total:.{nd}f}") / unit)
    raw = [p / unit for p in parts]
    low = [math.floor(x) for x in raw]
    order = sorted(range(len(raw)), key=lambda i: -(raw[i] - low[i]))  # stable: ties go to the first part
    for i in order[:max(t - sum(low), 0)]:
        low[i] += 1
    return round(t * unit, nd), [round(k * unit, nd) for k in low]


def main_cause(shares) -> str:
    """The name of the largest positive share (:data:`CAUSES` order breaks ties), ``""`` when none is positive.

    Examples
    --------
    >>> main_cause([4.0, 2.0, 0.5, -1.0]), main_cause([0.0, 0.0, 0.0, 0.0]), main_cause([1.0, 3.0, 3.0, 0.0])
    ('load', '', 'traction')
    """
    best, name = 0.0, ""
    for (n, _), x in zip(CAUSES, shares):
        if math.isfinite(x) and x > best:
            best, name = x, n
    return name


def _s(x: float) -> str:
    """Seconds to 0.1 s, never ``-0.0``, and never ``0.0`` for a value that is not zero (a leg is flagged by a
    value's sign: 0.03 s below its minimum must not read "0.0 s below"; :func:`planner.line.units.shown`)."""
    from planner.line.units import shown

    return shown(x, 1) if math.isfinite(x) else f"{x:.1f}"


def cost_words(cost: float, shares) -> str:
    """``the bad day costs 9.9 s (load 4.0, traction 3.0, adhesion 2.0, stop model 0.9 s)``, the parts adding up."""
    if not all(math.isfinite(x) for x in [cost, *shares]):
        return f"the bad day costs {cost:.1f} s"
    t, shown = added_up(cost, list(shares))
    parts = ", ".join(f"{n.replace('_', ' ')} {x:.1f}" for (n, _), x in zip(CAUSES, shown))
    return f"the bad day costs {t:.1f} s ({parts} s)"


def flag_reasons(rows, tight_threshold_s: float, arrival_error_threshold_s: float) -> tuple[list[str], list[str]]:
    """What each row's flags say, and the main cause of the bad day's cost where it decides a flag.

    Parameters
    ----------
    rows : pandas.DataFrame
        Margin rows with the flags, margins and the :data:`CAUSES` shares.
    tight_threshold_s, arrival_error_threshold_s : float
        The rule's thresholds [s] (:class:`planner.report.margin_rule.MarginRule`).

    Returns
    -------
    (list of str, list of str)
        ``flag_reason`` (every flag of the row in words, ``"; "`` between them; empty without a flag)
        and ``bad_day_cause`` (:func:`main_cause` of a leg short on the bad day or tight, else empty).
    """
    reasons, causes = [], []
    for r in rows.itertuples(index=False):
        shares = [float(getattr(r, c)) for _, c in CAUSES]
        cost = float(r.degraded_min_running_time_s - r.min_running_time_s)
        said, cause = [], ""
        for f in flags_of(r):
            if f == "unassessed":
                said.append(f"unassessed: {r.unassessed_reason}")
            elif f == "impossible":
                said.append(f"impossible: scheduled {r.scheduled_running_time_s:.1f} s, {_s(-r.margin_s)} s below "
                            f"the minimum running time {r.min_running_time_s:.1f} s: no driving makes it")
            elif f in ("short_bad_day", "tight"):
                cause = main_cause(shares)
                head = (f"short on a bad day by {_s(-r.remaining_margin_s)} s" if f == "short_bad_day" else
                        f"tight: {_s(r.remaining_margin_s)} s left on a bad day (below {tight_threshold_s:g} s)")
                said.append(f"{head}: margin {_s(r.margin_s)} s, {cost_words(cost, shares)}"
                            + (f", most of it {CAUSE_WORDS[cause]}" if cause else ""))
            elif f == "unreachable":
                said.append(f"unreachable: scheduled {r.scheduled_running_time_s:.1f} s, above the slowest table "
                            f"time {r.slowest_running_time_s:.1f} s: the train arrives early")
            elif f == "inaccurate":
                said.append(f"inaccurate: the closed loop misses the arrival by up to "
                            f"{r.closed_loop_max_error_s:.1f} s (threshold {arrival_error_threshold_s:g} s)")
        reasons.append("; ".join(said))
        causes.append(cause)
    return reasons, causes


def any_flag(rows, names=FLAGS) -> np.ndarray:
    """Rows with any of the flags ``names`` set (a column missing from an older run's rows counts as unset)."""
    out = np.zeros(len(rows), dtype=bool)
    for f in names:
        if f in rows:
            out |= rows[f].fillna(False).astype(bool).to_numpy()
    return out
