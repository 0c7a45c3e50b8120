"""The datasets of the day as it will run: the predicted day's network and delays, and the Monte Carlo statistics.

Takes a :class:`~planner.delay.predicted.PredictedDay` (and, when days were simulated,
:class:`~planner.delay.montecarlo.Stats`); gives the frames of ``delay_events``, ``delay_activities``,
``delay_conflicts``, ``robustness_trains``, ``robustness_stations`` and ``robustness_activities`` and writes
them (:func:`write_delays`, :func:`write_robustness`), partitioned by line.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from planner.delay.montecarlo import Stats, edge_index
from planner.delay.network import ACTIVITY_KINDS, ARRIVAL, EVENT_KINDS
from planner.delay.predicted import PredictedDay, cause_text
from planner.io.parquet import declare, write_parquet_atomic
from planner.io.paths import check_path_id

_EVENT = [
    ("train_id", pa.string(), "running train"),
    ("train_type", pa.string(), "its train type"),
    ("direction", pa.string(), "its running direction"),
    ("seq", pa.int32(), "the call's seq in timetable.parquet"),
    ("station_id", pa.string(), "station of the call"),
    ("event", pa.string(), "`arrival` or `departure`"),
    ("scheduled_s", pa.float64(), "scheduled time: the timetable [s after midnight]"),
]
DELAY_EVENTS_SCHEMA = declare(_EVENT + [
    ("computed_s", pa.float64(), "time of the conflict check's run curves with the day's restrictions, every leg run as scheduled or as fast as it can, no minimum dwell, no train waiting for another [s after midnight]"),
    ("predicted_s", pa.float64(), "predicted time: every delay carried forward (a late arrival delays the departure, never before arrival + the minimum dwell; a train held at a block or a crossing waits), no primary delay [s after midnight]"),
    ("delay_s", pa.float64(), "predicted_s − scheduled_s, never negative [s]"),
    ("own_delay_s", pa.float64(), "the delay the train would have alone on the line (its own legs and dwells) [s]"),
    ("knock_on_s", pa.float64(), "delay_s − own_delay_s: the delay other trains cause it [s]"),
    ("cause_kind", pa.string(), "what made the event later than the one before it: `run` (a leg longer than scheduled), `dwell` (the minimum dwell), `headway` (held by another train), `connection`; empty: on time, or the delay only carried on"),
    ("cause_train", pa.string(), "for `headway` and `connection`: the train it waits for"),
    ("cause", pa.string(), "the cause in words, with the place"),
], name="delay_events", description="The predicted day: one row per arrival and departure of each running train, scheduled and predicted, with the delay and where it comes from")
DELAY_ACTIVITIES_SCHEMA = declare([
    ("activity", pa.string(), "`run` (departure → next arrival), `dwell` (arrival → departure), `headway` (one train's event → the next train's on a shared switch or section) or `connection`"),
    ("from_train", pa.string(), "train of the event it starts from"),
    ("from_seq", pa.int32(), "that event's call seq"),
    ("from_station", pa.string(), "that event's station"),
    ("from_event", pa.string(), "`arrival` or `departure`"),
    ("to_train", pa.string(), "train of the event it leads to"),
    ("to_seq", pa.int32(), "that event's call seq"),
    ("to_station", pa.string(), "that event's station"),
    ("to_event", pa.string(), "`arrival` or `departure`"),
    ("min_s", pa.float64(), "minimum time from the first event to the second: the leg's minimum running time with the day's restrictions, the minimum dwell, the minimum headway (from the blocking times) or the connection's [s]"),
    ("scheduled_s", pa.float64(), "scheduled time between the two events [s]"),
    ("slack_s", pa.float64(), "scheduled_s − min_s: delay it absorbs; negative, delay it creates [s]"),
    ("place", pa.string(), "a headway's switch or section (resource id), a connection's station; else empty"),
    ("binding", pa.bool_(), "on the predicted day, this activity sets the later event's time (it is late because of it)"),
], name="delay_activities", description="The day's event–activity network: minimum times between the events of delay_events, in which delays propagate")
ROBUSTNESS_TRAINS_SCHEMA = declare(_EVENT + [
    ("station_name", pa.string(), "station name"),
    ("predicted_delay_s", pa.float64(), "delay on the predicted day (no primary delay) [s]"),
    ("mean_delay_s", pa.float64(), "mean delay over the simulated days [s]"),
    ("sem_s", pa.float64(), "standard error of mean_delay_s [s]"),
    ("p50_s", pa.float64(), "median delay: the upper edge of its 10 s bin (60 s beyond 10 min) [s]"),
    ("p90_s", pa.float64(), "90th percentile, as p50_s [s]"),
    ("p99_s", pa.float64(), "99th percentile, as p50_s [s]"),
    ("within_60s", pa.float64(), "share of days the event is at most 1 min late"),
    ("within_180s", pa.float64(), "share of days at most 3 min late"),
    ("within_300s", pa.float64(), "share of days at most 5 min late"),
    ("knock_on_s", pa.float64(), "mean knock-on delay: the delay the train would not have alone on the line [s]"),
    ("primary_s", pa.float64(), "mean primary delay drawn for the event itself [s]"),
], name="robustness_trains", description="Monte Carlo punctuality: each train's delay distribution at every event over the simulated days")
ROBUSTNESS_STATIONS_SCHEMA = declare([
    ("direction", pa.string(), "running direction"),
    ("station_id", pa.string(), "station"),
    ("station_name", pa.string(), "station name"),
    ("position_m", pa.float64(), "the station's position along the line [m]"),
    ("arrivals", pa.int32(), "train arrivals there in this direction per day"),
    ("within_60s", pa.float64(), "share of arrivals × days at most 1 min late"),
    ("within_180s", pa.float64(), "share at most 3 min late"),
    ("within_300s", pa.float64(), "share at most 5 min late"),
    ("mean_delay_s", pa.float64(), "mean arrival delay [s]"),
    ("knock_on_s", pa.float64(), "mean knock-on part of it [s]"),
], name="robustness_stations", description="Monte Carlo punctuality at each station and direction: share of arrivals within 1, 3 and 5 min")
ROBUSTNESS_ACTIVITIES_SCHEMA = declare([
    ("activity", pa.string(), "`run`, `dwell`, `headway` or `connection` (delay_activities)"),
    ("from_train", pa.string(), "train of the event it starts from"),
    ("to_train", pa.string(), "train of the event it leads to"),
    ("from_station", pa.string(), "station of the event it starts from"),
    ("to_station", pa.string(), "station of the event it leads to"),
    ("place", pa.string(), "a headway's switch or section, in words; a connection's station; else empty"),
    ("min_s", pa.float64(), "minimum time [s]"),
    ("slack_s", pa.float64(), "scheduled − minimum time [s]"),
    ("transmitted_s", pa.float64(), "mean delay per day it passed on: on days it sets its later event's delay, that delay [s]"),
    ("binding_share", pa.float64(), "share of days it sets its later event's delay"),
    ("absorbed_s", pa.float64(), "mean delay per day its slack absorbed: min(delay of its first event, slack) where both are positive [s]"),
], name="robustness_activities", description="Monte Carlo: how much delay each activity passes on and how much its slack absorbs")
DELAY_CONFLICTS_SCHEMA = declare([
    ("train_a", pa.string(), "the train that goes first"),
    ("train_b", pa.string(), "the train that waits for it"),
    ("activity", pa.string(), "`headway` (a switch or section train_a holds) or `connection`"),
    ("resource_id", pa.string(), "the switch or section (a connection: its station)"),
    ("place", pa.string(), "where that is, in words (station, track)"),
    ("station_id", pa.string(), "station of train_b's event that waits"),
    ("seq", pa.int32(), "its call seq"),
    ("event", pa.string(), "`departure` (it waits at the stop) or `arrival`"),
    ("scheduled_s", pa.float64(), "that event's scheduled time [s after midnight]"),
    ("hold_s", pa.float64(), "how long train_b waits: its delay there beyond what its own runs and dwells give it [s]"),
    ("knock_on", pa.bool_(), "the pair does not conflict at this place in the timetable as planned (the conflicts dataset): the late trains cause it"),
], name="delay_conflicts", description="The conflicts of the day as it will run: every wait of a train for another on the predicted day, cascades included, and whether the timetable as planned has it")
SCHEMAS = {"delay_events": DELAY_EVENTS_SCHEMA, "delay_activities": DELAY_ACTIVITIES_SCHEMA,
           "delay_conflicts": DELAY_CONFLICTS_SCHEMA,
           "robustness_trains": ROBUSTNESS_TRAINS_SCHEMA, "robustness_stations": ROBUSTNESS_STATIONS_SCHEMA,
           "robustness_activities": ROBUSTNESS_ACTIVITIES_SCHEMA}


def _event_cols(day: PredictedDay, directions: dict[str, str]) -> dict:
    net = day.net
    ids = np.asarray(net.train_ids, dtype=object)[net.ev_train]
    return {"train_id": ids, "train_type": np.asarray(net.train_types, dtype=object)[net.ev_train],
            "direction": [directions[t] for t in ids],
            "seq": net.ev_seq.astype(np.int32), "station_id": list(net.ev_station),
            "event": np.asarray(EVENT_KINDS, dtype=object)[net.ev_kind], "scheduled_s": net.sched_s}


def events_frame(day: PredictedDay, directions: dict[str, str]) -> pd.DataFrame:
    """Rows of ``delay_events``; ``directions``: train_id → direction."""
    net = day.net
    cols = _event_cols(day, directions)
    # an event's cause is named where it has words (cause_text): the activity that set it, and for a wait its train
    texts = [cause_text(day, e) for e in range(net.n_events)]
    kind = np.full(net.n_events, "", dtype=object)
    other = np.full(net.n_events, "", dtype=object)
    for e in (e for e, t in enumerate(texts) if t):
        a = int(day.cause[e])
        kind[e] = ACTIVITY_KINDS[int(net.act_kind[a])]
        if kind[e] in ("headway", "connection"):
            other[e] = net.train_ids[int(net.ev_train[net.act_src[a]])]
    return pd.DataFrame(cols | {"computed_s": net.plan_s, "predicted_s": net.sched_s + day.delay_s,
                                "delay_s": day.delay_s, "own_delay_s": day.own_s,
                                "knock_on_s": day.delay_s - day.own_s, "cause_kind": kind, "cause_train": other,
                                "cause": texts})


def activities_frame(day: PredictedDay) -> pd.DataFrame:
    """Rows of ``delay_activities``."""
    net = day.net
    ids = np.asarray(net.train_ids, dtype=object)
    kinds = np.asarray(EVENT_KINDS, dtype=object)
    s, d = net.act_src, net.act_dst
    st = np.asarray(net.ev_station, dtype=object)
    bind = np.zeros(net.n_activities, dtype=bool)
    bind[day.cause[day.cause >= 0]] = True
    return pd.DataFrame({"activity": np.asarray(ACTIVITY_KINDS, dtype=object)[net.act_kind],
                         "from_train": ids[net.ev_train[s]], "from_seq": net.ev_seq[s].astype(np.int32),
                         "from_station": st[s], "from_event": kinds[net.ev_kind[s]],
                         "to_train": ids[net.ev_train[d]], "to_seq": net.ev_seq[d].astype(np.int32),
                         "to_station": st[d], "to_event": kinds[net.ev_kind[d]], "min_s": net.min_s,
                         "scheduled_s": net.sched_s[d] - net.sched_s[s], "slack_s": net.slack_s,
                         "place": list(net.act_place), "binding": bind})


def robustness_frames(day: PredictedDay, stats: Stats, line, directions: dict[str, str]):
    """Frames of ``robustness_trains``, ``robustness_stations`` and ``robustness_activities``."""
    net = day.net
    cols = _event_cols(day, directions)
    names = {s.station_id: s.name for s in line.stations}
    trains = pd.DataFrame(cols | {
        "station_name": [names.get(s, s) for s in net.ev_station], "predicted_delay_s": day.delay_s,
        "mean_delay_s": stats.mean_s, "sem_s": stats.sem_s, "p50_s": stats.quantile_s(0.5),
        "p90_s": stats.quantile_s(0.9), "p99_s": stats.quantile_s(0.99), "within_60s": stats.within(60.0),
        "within_180s": stats.within(180.0), "within_300s": stats.within(300.0), "knock_on_s": stats.knock_on_s,
        "primary_s": stats.primary_sum_s / stats.days})
    arr = net.ev_kind == ARRIVAL
    pos = {s.station_id: s.position_m for s in line.stations}
    st = []
    for (direction, sid), idx in trains[arr].groupby(["direction", "station_id"], sort=True).groups.items():
        ii = np.asarray(trains.index.get_indexer(idx))
        n = len(ii)
        h = stats.hist[ii]
        st.append({"direction": direction, "station_id": sid, "station_name": names.get(sid, sid),
                   "position_m": float(pos.get(sid, np.nan)), "arrivals": n,
                   **{f"within_{m}s": float(h[:, :edge_index(m) + 1].sum() / (n * stats.days)) for m in (60, 180, 300)},
                   "mean_delay_s": float(stats.mean_s[ii].mean()), "knock_on_s": float(stats.knock_on_s[ii].mean())})
    stations = pd.DataFrame(st, columns=[f.name for f in ROBUSTNESS_STATIONS_SCHEMA])
    stations = stations.sort_values(["direction", "position_m", "station_id"], kind="stable").reset_index(drop=True)
    ids = np.asarray(net.train_ids, dtype=object)
    stn = np.asarray(net.ev_station, dtype=object)
    s, d = net.act_src, net.act_dst
    acts = pd.DataFrame({"activity": np.asarray(ACTIVITY_KINDS, dtype=object)[net.act_kind],
                         "from_train": ids[net.ev_train[s]], "to_train": ids[net.ev_train[d]],
                         "from_station": stn[s], "to_station": stn[d],
                         "place": [net.places.get(p, p) for p in net.act_place], "min_s": net.min_s,
                         "slack_s": net.slack_s, "transmitted_s": stats.push_s / stats.days,
                         "binding_share": stats.binds / stats.days, "absorbed_s": stats.absorbed_s / stats.days})
    return trains, stations, acts


def part_path(out: Path, name: str, line_id: str, part: str = "0") -> Path:
    """The file of dataset ``name`` that holds a line's part ``part`` (a section's rows,
    :mod:`planner.network.sections`; ``0`` for the whole line)."""
    return (Path(out) / name / f"line={check_path_id(line_id, 'line id ')}"
            / f"part-{check_path_id(part, 'part ')}.parquet")


def read_part(out: Path, name: str, line_id: str, part: str, columns: list[str]) -> pd.DataFrame | None:
    """The rows of a line's part of dataset ``name`` (:func:`part_path`), ``columns`` only; None without the file
    (a run that does not compute the day as it runs)."""
    import pyarrow.parquet as pq

    path = part_path(out, name, line_id, part)
    return pq.read_table(path, columns=columns).to_pandas() if path.is_file() else None


def _write(frame: pd.DataFrame, schema: pa.Schema, out: Path, name: str, line_id: str, part: str = "0") -> Path:
    path = part_path(out, name, line_id, part)
    table = pa.Table.from_pandas(frame[[f.name for f in schema]], preserve_index=False, schema=schema) \
        if len(frame) else schema.empty_table()
    write_parquet_atomic(table, path)
    return path


def write_delays(day: PredictedDay, line_id: str, directions: dict[str, str], out, held=(), part: str = "0"
                 ) -> list[Path]:
    """Write ``delay_events``, ``delay_activities`` and ``delay_conflicts`` (``held``:
    :func:`planner.delay.predicted.holds`) of the predicted day (one file each, by line: ``part-<part>.parquet``,
    a part per section of a line checked in sections, :mod:`planner.network.sections`)."""
    con = pd.DataFrame.from_records(list(held), columns=[f.name for f in DELAY_CONFLICTS_SCHEMA])
    return [_write(events_frame(day, directions), DELAY_EVENTS_SCHEMA, out, "delay_events", line_id, part),
            _write(activities_frame(day), DELAY_ACTIVITIES_SCHEMA, out, "delay_activities", line_id, part),
            _write(con, DELAY_CONFLICTS_SCHEMA, out, "delay_conflicts", line_id, part)]


def write_day(day: PredictedDay, stats: Stats | None, held, line, directions: dict[str, str], out, part: str = "0"):
    """Every dataset of the day as it runs (:func:`write_delays`, and :func:`write_robustness` when days were
    simulated): ``(files written, the robustness frames or None)``; the nightly job and ``planner robustness``
    both write through it."""
    files = write_delays(day, line.line_id, directions, out, held, part)
    frames = robustness_frames(day, stats, line, directions) if stats is not None else None
    if frames is not None:
        files += write_robustness(frames, line.line_id, out, part)
    return files, frames


def write_robustness(frames, line_id: str, out, part: str = "0") -> list[Path]:
    """Write ``robustness_trains``, ``robustness_stations`` and ``robustness_activities`` (one file each per part)."""
    names = ("robustness_trains", "robustness_stations", "robustness_activities")
    return [_write(f, SCHEMAS[n], out, n, line_id, part) for f, n in zip(frames, names)]
