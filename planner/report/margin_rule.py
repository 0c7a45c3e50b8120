"""The margin rule and what follows from plain numbers: rounding, margins, flags, totals (pure).

Takes minimum, scheduled, bad-day and slowest running times of legs (arrays
[s]) and gives the margin columns and flags of each leg (:func:`margin_columns`),
and the totals per train, per direction x train type and per direction
(:func:`margin_totals`). No simulator and no files: the numbers come from
:func:`planner.report.margins.compute_margins`, which documents every column.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from planner.errors import InputError

ROUND_UNIT_S = 10.0
"""Timetable unit the minimum running time is rounded up to [s]."""
TIME_TOL_S = 1e-6
"""Two times closer than this [s] are equal (flags, rounding): far below the integrator's 0.05 s."""
ALL_TYPES = "all"
"""``train_type`` partition value of the per-direction totals over every train type."""


@dataclass(frozen=True)
class MarginRule:
    """What the report asks of a timetable (job file ``[margins]``).

    Attributes
    ----------
    supplement_percent : float
        Required supplement as a percentage of the minimum running time [%].
    supplement_min_per_100km : float
        ... plus this many minutes per 100 km of leg length [min/100 km].
    tight_threshold_s : float
        A remaining margin (scheduled − degraded minimum) below this is ``tight`` [s].
    degraded_load : float
        Load factor of the degraded conditions (1.0 = full).
    degraded_traction : float
        Traction factor of the degraded conditions (0.9 = weak catenary).
    bad_day_load, bad_day_traction, bad_day_adhesion : bool
        Which effects the bad day (degraded scenario) includes. An effect that
        is off takes its nominal value: load 0, traction × 1.0, and the
        stopping brake of the running-time tables instead of a low-adhesion
        stopping pattern.
    degraded_adhesion_kmh_s : float
        Adhesion-limited deceleration of the bad day's stop [km/h/s]; 0 = the
        lowest level of the adhesion sweep.
    arrival_error_threshold_s : float
        A leg whose closed-loop sweep misses the designated arrival by more than this
        (worst |error| over the job's scenarios and modes) is flagged ``inaccurate`` [s]; 0 = off.
        The sample line's worst is 5.3 s; a 60 km leg without evaluation points misses by up to 60 s.
    """

    supplement_percent: float = 3.0
    supplement_min_per_100km: float = 1.0
    tight_threshold_s: float = 5.0
    degraded_load: float = 1.0
    degraded_traction: float = 0.9
    bad_day_load: bool = True
    bad_day_traction: bool = True
    bad_day_adhesion: bool = True
    degraded_adhesion_kmh_s: float = 0.0
    arrival_error_threshold_s: float = 10.0

    def __post_init__(self):
        for name in ("supplement_percent", "supplement_min_per_100km", "tight_threshold_s", "degraded_load",
                     "degraded_adhesion_kmh_s", "arrival_error_threshold_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"[margins] {name} must be a number ≥ 0, found {v!r}")
        if self.degraded_load > 1:
            raise InputError(f"[margins] degraded_load must lie between 0 (empty) and 1 (full), "
                             f"found {self.degraded_load!r}")
        if not (math.isfinite(self.degraded_traction) and 0 < self.degraded_traction <= 2):
            raise InputError(f"[margins] degraded_traction must lie in (0, 2], found {self.degraded_traction!r}")

    @property
    def bad_load(self) -> float:
        """Load factor of the bad day as configured (0, the tables' load, when the effect is off)."""
        return self.degraded_load if self.bad_day_load else 0.0

    @property
    def bad_traction(self) -> float:
        """Traction factor of the bad day as configured (1.0 when the effect is off)."""
        return self.degraded_traction if self.bad_day_traction else 1.0

    def bad_adhesion_kmh_s(self, sweep_kmh_s) -> float | None:
        """Adhesion of the bad day's stop [km/h/s]: the configured value or the sweep's lowest; None when off."""
        if not self.bad_day_adhesion:
            return None
        return float(self.degraded_adhesion_kmh_s) if self.degraded_adhesion_kmh_s > 0 else float(
            np.min(np.asarray(sweep_kmh_s, dtype=float)))

    def describe(self, sweep_kmh_s) -> str:
        """The bad day in words, e.g. ``load 100 %, traction × 0.9, adhesion 2.5 km/h/s``."""
        parts = [f"load {self.degraded_load:.0%}" if self.bad_day_load else "load off (empty)",
                 f"traction ×{self.degraded_traction:g}" if self.bad_day_traction else "traction off (×1)"]
        a = self.bad_adhesion_kmh_s(sweep_kmh_s)
        parts.append(f"adhesion {a:g} km/h/s" if a is not None else "adhesion off (stopping brake)")
        return ", ".join(parts)

    @classmethod
    def from_section(cls, section) -> "MarginRule":
        """From a :class:`planner.job.config.MarginsSection` (or anything with the same attributes)."""
        return cls(**{f: getattr(section, f) for f in cls.__dataclass_fields__})

    def required_supplement_s(self, min_time_s, length_m):
        """Supplement the rule asks for [s].

        ``S = p/100 · T_min + m · 60 · L / 100 000`` with p = ``supplement_percent``,
        m = ``supplement_min_per_100km``, T_min [s], L [m].

        Examples
        --------
        >>> round(MarginRule().required_supplement_s(100.0, 50_000.0), 6)
        33.0
        """
        t = np.asarray(min_time_s, dtype=float)
        L = np.asarray(length_m, dtype=float)
        return self.supplement_percent / 100.0 * t + self.supplement_min_per_100km * 60.0 * L / 100_000.0


def round_up_s(t_s, unit_s: float = ROUND_UNIT_S):
    """Round a running time up to the timetable unit (10 s) [s].

    A time within :data:`TIME_TOL_S` above a multiple stays on it (so 130.0
    computed as 130.0000000001 is 130, not 140).

    Examples
    --------
    >>> round_up_s(135.78), round_up_s(130.0), round_up_s(130.2)
    (140.0, 130.0, 140.0)
    """
    t = np.asarray(t_s, dtype=float)
    out = np.ceil((t - TIME_TOL_S) / unit_s) * unit_s
    return float(out) if out.ndim == 0 else out


def margin_columns(min_time_s, scheduled_s, degraded_min_s, slowest_time_s, length_m,
                   rule: MarginRule = MarginRule(), closed_loop_error_s=math.nan) -> dict[str, np.ndarray]:
    """Margins, supplement and flags of legs, from plain numbers (arrays of equal shape).

    Parameters
    ----------
    min_time_s : array
        Minimum running time (ratio 1.0, nominal) [s].
    scheduled_s : array
        Scheduled running time [s]; NaN where no train runs the leg.
    degraded_min_s : array
        Minimum running time under degraded conditions [s].
    slowest_time_s : array
        Slowest table time (lowest ratio of table (a)) [s].
    length_m : array
        Leg length, stop marker to stop marker [m].
    rule : MarginRule
    closed_loop_error_s : array, optional
        Worst closed-loop |arrival error| of the leg [s]; NaN where unknown (never flagged).

    Returns
    -------
    dict of ndarray
        ``min_running_time_rounded_s``, ``margin_s`` (scheduled − minimum),
        ``margin_percent`` (of the minimum), ``remaining_margin_s``
        (scheduled − degraded minimum), ``supplement_required_s``,
        ``supplement_met`` (margin ≥ required), ``supplement_shortfall_s``
        (required − margin, ≥ 0), and the flags ``impossible`` (scheduled <
        minimum: no driving makes it), ``short_bad_day`` (not impossible, but
        scheduled < degraded minimum), ``infeasible`` (either of the two, kept
        for compatibility), ``tight`` (not infeasible and remaining margin <
        threshold), ``unreachable`` (scheduled > slowest), ``unassessed``
        (minimum or degraded minimum not finite: short, infeasible and tight cannot
        be decided and are False here, impossible too when the minimum is unknown;
        :func:`planner.report.margin_datasets.datasets` writes them as null),
        ``inaccurate`` (closed-loop error above ``arrival_error_threshold_s``, whether
        or not a train runs the leg).
        Times within :data:`TIME_TOL_S` count as equal; infeasible, tight and
        unreachable are False where there is no schedule.
    """
    tmin = np.asarray(min_time_s, dtype=float)
    sched = np.broadcast_to(np.asarray(scheduled_s, dtype=float), tmin.shape)
    deg = np.broadcast_to(np.asarray(degraded_min_s, dtype=float), tmin.shape)
    slow = np.broadcast_to(np.asarray(slowest_time_s, dtype=float), tmin.shape)
    has = np.isfinite(sched)
    margin = sched - tmin
    remaining = sched - deg
    req = np.broadcast_to(rule.required_supplement_s(tmin, length_m), tmin.shape)
    cl = np.broadcast_to(np.asarray(closed_loop_error_s, dtype=float), tmin.shape)
    with np.errstate(invalid="ignore"):
        impossible = has & (sched < tmin - TIME_TOL_S)
        short = has & ~impossible & (sched < deg - TIME_TOL_S)
        infeasible = impossible | short
        return {
            "min_running_time_rounded_s": np.asarray(round_up_s(tmin), dtype=float).reshape(tmin.shape),
            "margin_s": margin,
            "margin_percent": 100.0 * margin / tmin,
            "remaining_margin_s": remaining,
            "supplement_required_s": np.array(req, dtype=float),
            "supplement_met": has & (margin >= req - TIME_TOL_S),
            "supplement_shortfall_s": np.where(has, np.maximum(req - margin, 0.0), np.nan),
            "impossible": impossible,
            "short_bad_day": short,
            "infeasible": infeasible,
            "tight": has & ~infeasible & (remaining < rule.tight_threshold_s - TIME_TOL_S),
            "unreachable": has & (sched > slow + TIME_TOL_S),
            "unassessed": ~(np.isfinite(tmin) & np.isfinite(deg)),
            "inaccurate": (rule.arrival_error_threshold_s > 0) & np.isfinite(cl)
            & (cl > rule.arrival_error_threshold_s + TIME_TOL_S),
        }


TOTAL_SUM_COLS = (
    "min_running_time_s", "min_running_time_rounded_s", "scheduled_running_time_s", "margin_s",
    "degraded_min_running_time_s", "remaining_margin_s", "supplement_required_s",
    "energy_at_ratio_kwh", "energy_at_full_ratio_kwh", "energy_saved_kwh",
)
"""Row columns summed into the totals."""
UNKNOWN_WHEN_UNASSESSED = ("degraded_min_running_time_s", "remaining_margin_s")
"""Totals that are NaN (unknown) when any leg summed is unassessed, as are the worst margin and the shortfall."""


TOTALS_COLUMNS = [
    "level", "train_id", "direction", "train_type", "origin", "destination", "first_departure_s", "n_trains",
    "n_legs", *TOTAL_SUM_COLS, "margin_percent", "min_remaining_margin_s", "bad_day_shortfall_s",
    "n_supplement_short",
    "n_impossible", "n_short_bad_day", "n_infeasible", "n_tight", "n_unreachable", "n_unassessed", "n_inaccurate",
]
"""Columns of the totals frame (and the ``margin_totals`` dataset), in order."""
COUNTED = ("impossible", "short_bad_day", "infeasible", "tight", "unreachable", "unassessed", "inaccurate")
"""The flags counted in the totals (``n_<flag>``)."""


def margin_totals(rows, train_legs, key_extra: Sequence[str] = ()):
    """Totals per train, per direction × train type and per direction (pure pandas).

    Parameters
    ----------
    rows : pandas.DataFrame
        Margin rows (:func:`compute_margins`), with at least the key columns
        ``direction, train_type, origin, destination, scheduled_running_time_s``,
        the :data:`TOTAL_SUM_COLS` and the flags.
    train_legs : pandas.DataFrame
        One row per train and leg: ``train_id, direction, train_type, origin,
        destination, scheduled_running_time_s, departure_s, leg_seq``.
    key_extra : sequence of str
        More columns of both that tell a train's row apart (the margin report's lifted restrictions,
        when a leg has rows for trains computed without some of them).

    Returns
    -------
    pandas.DataFrame
        ``level`` (``train``, ``type``, ``line``), ``train_id`` (null unless
        level train), ``direction``, ``train_type`` (``all`` for level line),
        ``origin``/``destination`` (the train's first and last stop; null
        otherwise), ``first_departure_s``, ``n_trains``, ``n_legs``, the sums
        of :data:`TOTAL_SUM_COLS`, ``margin_percent`` (total margin / total
        minimum), ``min_remaining_margin_s`` (worst leg), ``bad_day_shortfall_s``
        (sum of max(0, −remaining margin) over the legs), ``n_supplement_short``,
        ``n_impossible``, ``n_short_bad_day``, ``n_infeasible`` (the two together),
        ``n_tight``, ``n_unreachable``, ``n_unassessed``, ``n_inaccurate``
        (legs, counted per train run). With an unassessed leg among those
        summed, the degraded-minimum and remaining-margin sums, the worst
        remaining margin and the shortfall are NaN: unknown, not partial.
    """
    import pandas as pd

    key = ["direction", "train_type", "origin", "destination", "scheduled_running_time_s", *key_extra]
    cols = key + [c for c in TOTAL_SUM_COLS if c not in key] + ["supplement_met", *COUNTED]
    r = rows[rows["scheduled_running_time_s"].notna()][cols]
    legs = train_legs.merge(r, on=key, how="left", validate="many_to_one")
    if legs["min_running_time_s"].isna().any():
        bad = legs[legs["min_running_time_s"].isna()].iloc[0]
        raise ValueError(f"train {bad.train_id}: leg {bad.origin}->{bad.destination} has no margin row")
    legs = legs.assign(short=~legs["supplement_met"].astype(bool),
                       **{f"n_{f}": legs[f].astype(int) for f in COUNTED})
    legs = legs.sort_values(["train_id", "leg_seq"], kind="stable")

    # each column once as an array, each group as row positions: the sums are numpy's over the same
    # values in the same order as pandas' per-group Series.sum (NaN skipped as zeros), so the same bits
    f = {c: legs[c].to_numpy(float) for c in (*TOTAL_SUM_COLS, "departure_s")}
    n = {c: legs[c].to_numpy(int) for c in ("short", *(f"n_{f}" for f in COUNTED))}
    # the trains as codes (the rows as text would be a Python string a row: 30 MB a column on a 100x line, at the
    # job process's peak); the text columns read at the rows that start or end a train only
    codes, names = pd.factorize(legs["train_id"])
    names = np.asarray(names, dtype=object)

    def agg(at: np.ndarray) -> dict:
        """The figures of the groups whose rows are ``at``: one group's positions (1-D), or several groups of as
        many rows each, a group a row (2-D). Each sum is numpy's over a row of the group's values in ``legs``
        order: a row of a C-ordered 2-D array is summed as that row alone would be, so the same bits."""
        one = at.ndim == 1
        at = np.atleast_2d(at)
        out = {}
        for c in TOTAL_SUM_COLS:
            x = f[c][at]
            out[c] = np.where(np.isnan(x), 0.0, x).sum(axis=1)
        for c in UNKNOWN_WHEN_UNASSESSED:  # a partial sum would pass for the whole: unknown instead
            out[c] = f[c][at].sum(axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            out["margin_percent"] = 100.0 * out["margin_s"] / out["min_running_time_s"]
        rm = f["remaining_margin_s"][at]
        out["min_remaining_margin_s"] = rm.min(axis=1)  # NaN when one is unknown
        out["bad_day_shortfall_s"] = np.maximum(-rm, 0.0).sum(axis=1)
        out["n_legs"] = np.full(len(at), at.shape[1], dtype=np.int64)
        out["n_supplement_short"] = n["short"][at].sum(axis=1)
        for flag in COUNTED:
            out[f"n_{flag}"] = n[f"n_{flag}"][at].sum(axis=1)
        out["first_departure_s"] = np.fmin.reduce(f["departure_s"][at], axis=1)
        if one:
            return {k: int(v[0]) if v.dtype.kind in "iu" else float(v[0]) for k, v in out.items()}
        return out

    def groups(by) -> list:
        """(key, row positions in ``legs`` order) of each group, keys sorted (as groupby's)."""
        idx = legs.groupby(by, sort=True).indices
        return [(k, idx[k]) for k in sorted(idx)]

    # the trains' level, a column at a time, the trains with as many legs as each other together: a train's legs
    # are one block of rows in ``legs`` (sorted by train id, as groupby sorts its keys)
    starts = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]]) if len(codes) else np.zeros(0, dtype=np.int64)
    sizes = np.diff(np.r_[starts, len(codes)])

    def at_rows(c: str, at: np.ndarray) -> np.ndarray:
        return legs[c].iloc[at].to_numpy(object)

    each = {"level": ["train"] * len(starts), "train_id": names[codes[starts]],
            "direction": at_rows("direction", starts), "train_type": at_rows("train_type", starts),
            "origin": at_rows("origin", starts), "destination": at_rows("destination", starts + sizes - 1),
            "n_trains": np.ones(len(starts), dtype=np.int64)}
    got: dict[str, np.ndarray] = {}
    for size in np.unique(sizes):
        which = np.flatnonzero(sizes == size)
        for k, v in agg(starts[which][:, None] + np.arange(size)).items():
            got.setdefault(k, np.zeros(len(starts), dtype=v.dtype))[which] = v
    each |= got
    # the columns as plain values, as records would give them: the same column types
    columns = {c: np.asarray(each[c]).tolist() if c in each else [] for c in TOTALS_COLUMNS}
    recs = []
    for (d, t), at in groups(["direction", "train_type"]):
        recs.append({"level": "type", "train_id": None, "direction": d, "train_type": t, "origin": None,
                     "destination": None, "n_trains": len(np.unique(codes[at]))} | agg(at))
    for d, at in groups("direction"):
        recs.append({"level": "line", "train_id": None, "direction": d, "train_type": ALL_TYPES,
                     "origin": None, "destination": None, "n_trains": len(np.unique(codes[at]))} | agg(at))
    for r in recs:
        for c in TOTALS_COLUMNS:
            columns[c].append(r[c])
    return pd.DataFrame(columns, columns=TOTALS_COLUMNS)


