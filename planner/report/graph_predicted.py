"""The predicted day on the train graph: each late train's events as the ``delay_events`` dataset predicts them.

The graph's lines are the trains' runs from the run curves as timetabled (a run slower than the schedule makes
the train late, the next dwell absorbs it). The *predicted day* (:mod:`planner.delay.predicted`, the
``delay_events`` dataset) carries every delay forward: a late arrival delays the next departure, never before
arrival + a minimum dwell, and a train held by another at a block waits. The page draws it beside the lines as
a dashed run per late train, from the points gathered here: one per event (arrival, departure), at the event's
predicted time and its station's stop marker for the train's direction, where the train's drawn run stands at
a stop (:meth:`planner.line.model.Station.stop_m`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from planner.delay.predicted import LATE_S  # a train is late when an event is more than this late: every page's

__all__ = ["LATE_S", "PREDICTED_COLUMNS", "PredictedPath", "first_largest", "predicted_paths", "largest_delay"]

PREDICTED_COLUMNS = ("train_id", "seq", "station_id", "event", "scheduled_s", "predicted_s", "delay_s", "cause")
"""What the graph reads of ``delay_events``."""


@dataclass(frozen=True, eq=False)
class PredictedPath:
    """One late train on the predicted day, a point per event in running order.

    Attributes
    ----------
    station_ids, events : tuple of str
        Station and ``arrival``/``departure`` of each event.
    scheduled_s, t_s : ndarray
        Scheduled and predicted time [s after midnight].
    x_m : ndarray
        The station's stop marker for the train's direction [m].
    delay_s : ndarray
        Predicted − scheduled, never negative [s].
    causes : tuple of str
        Why the event is later than the train's event before it (``""``: it only carries a delay on).
    """

    train_id: str
    direction: str
    station_ids: tuple[str, ...]
    events: tuple[str, ...]
    scheduled_s: np.ndarray
    t_s: np.ndarray
    x_m: np.ndarray
    delay_s: np.ndarray
    causes: tuple[str, ...]

    @property
    def late(self) -> np.ndarray:
        """Indices of the events more than :data:`LATE_S` late."""
        return np.flatnonzero(self.delay_s > LATE_S)

    @property
    def max_delay_s(self) -> float:
        return float(self.delay_s.max()) if len(self.delay_s) else 0.0


def predicted_paths(line, events, trains: Sequence) -> dict[str, PredictedPath]:
    """``train_id`` → :class:`PredictedPath` of each train of ``trains`` (the graph's
    :class:`planner.report.train_graph.TrainPath`) late on the predicted day, in the order of ``trains``.

    Parameters
    ----------
    line : Line
        The line (its stations' stop markers).
    events : DataFrame
        ``delay_events`` rows of the line, at least :data:`PREDICTED_COLUMNS`; rows of trains not in ``trains``
        and events without a predicted time are left out.
    """
    if events is None or not len(events):
        return {}
    ev = events[list(PREDICTED_COLUMNS)].copy()
    ev = ev[np.isfinite(ev["predicted_s"].to_numpy(float))]
    ev["_k"] = (ev["event"] != "arrival").astype(int)  # a call's arrival before its departure
    ev = ev.sort_values(["train_id", "seq", "_k"], kind="stable")
    rows = ev.groupby("train_id", sort=False).indices
    # the columns as arrays once, each train's rows taken from them (a frame's row selection per train was most of
    # the page's time on a line of 35,600 trains)
    col = {c: ev[c].to_numpy(dtype=float if c in ("delay_s", "scheduled_s", "predicted_s") else object)
           for c in ("delay_s", "station_id", "event", "scheduled_s", "predicted_s", "cause")}
    stops: dict[tuple[str, str], float] = {}
    out = {}
    for tp in trains:
        ix = rows.get(tp.train_id)
        if ix is None:
            continue
        delay = np.maximum(col["delay_s"][ix], 0.0)
        if not (delay > LATE_S).any():
            continue
        sids = tuple(str(s) for s in col["station_id"][ix])
        for s in sids:
            if (s, tp.direction) not in stops:
                stops[(s, tp.direction)] = float(line.station(s).stop_m(tp.direction))
        out[tp.train_id] = PredictedPath(
            tp.train_id, tp.direction, sids, tuple(str(e) for e in col["event"][ix]), col["scheduled_s"][ix],
            col["predicted_s"][ix], np.array([stops[(s, tp.direction)] for s in sids]), delay,
            tuple("" if c is None else str(c) for c in col["cause"][ix]))
    return out


def first_largest(values: Sequence[float]) -> int | None:
    """The index of the largest of ``values``, the first of equals (within 1e-9); None when there are none."""
    best = None
    for k, v in enumerate(values):
        if best is None or v > values[best] + 1e-9:
            best = k
    return best


def largest_delay(predicted: dict[str, PredictedPath]) -> tuple[PredictedPath, int] | None:
    """The late train and event index of the day's largest delay (the first of equals, in the graph's order)."""
    paths = list(predicted.values())
    k = first_largest([float(p.delay_s[int(np.argmax(p.delay_s))]) for p in paths])
    return None if k is None else (paths[k], int(np.argmax(paths[k].delay_s)))
