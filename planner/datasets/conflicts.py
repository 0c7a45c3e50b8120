"""The ``conflicts``, ``headways`` and ``occupation`` datasets of the conflict check, its summary, and their writer.

Takes a :class:`~planner.network.check.ConflictCheck` (computed by
:func:`planner.network.check.check_timetable`); gives a
:class:`ConflictReport` whose ``conflicts`` and ``occupation`` are pandas
DataFrames with the columns of :data:`CONFLICTS_SCHEMA` and
:data:`OCCUPATION_SCHEMA`, the summary the CLI prints, and the Parquet
datasets (:func:`write_conflicts`). docs/design.md §8 and §9.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd
import pyarrow as pa

from planner.io.parquet import declare, write_parquet_atomic, write_partitioned
from planner.io.paths import check_path_id
from planner.line.model import Line
from planner.network.arrivals import RunCurveSource
from planner.network.check import ConflictCheck, check_timetable
from planner.network.routes import KIND_NAMES, Route, TrackGraph
from planner.network.windows import BlockingParams, Windows

OCCUPATION_SCHEMA = declare([
    ("train_id", pa.string(), "timetabled train"),
    ("seq", pa.int32(), "order of the resource along the train's route, from 0"),
    ("resource_kind", pa.string(), "`node` (a switch) or `section` (a track piece, edge)"),
    ("resource_id", pa.string(), "node_id or edge_id in nodes.parquet / edges.parquet"),
    ("interlocking", pa.string(), "interlocking controlling the resource (of its entry node for a section)"),
    ("track", pa.string(), "track name of the section, or of the node"),
    ("from_m", pa.float64(), "chainage where the front enters the resource [m]"),
    ("to_m", pa.float64(), "chainage where the front leaves the resource [m]"),
    ("entry_s", pa.float64(), "predicted time the front enters the resource: passes its entry, or departs where it stands there [s after midnight]"),
    ("exit_s", pa.float64(), "predicted time the front reaches the exit [s after midnight]"),
    ("clear_s", pa.float64(), "predicted time the tail clears the exit (front one train length past it) [s after midnight]"),
    ("setting_s", pa.float64(), "route setting time before the approach [s]"),
    ("approach_s", pa.float64(), "sight/reaction and approach time before the entry [s]"),
    ("running_s", pa.float64(), "running time of the front through the resource, exit − entry; includes a dwell only where the train stops with its front inside the resource [s]"),
    ("clearing_s", pa.float64(), "clearing time: tail clears the exit after the front reached it [s]"),
    ("release_s", pa.float64(), "route release time after clearing [s]"),
    ("start_s", pa.float64(), "window opens: entry − setting − approach [s after midnight]"),
    ("end_s", pa.float64(), "window closes: clear + release [s after midnight]"),
    ("predicted_start_s", pa.float64(), "the window's opening on the predicted day: every delay carried forward, a train held by another waiting before the resource (delay_events; docs/robustness.md); where the predicted day is not computed (`planner conflicts`), start_s [s after midnight]"),
    ("predicted_end_s", pa.float64(), "the window's close on the predicted day [s after midnight]"),
], name="occupation", description="Blocking-time occupation windows of every train on every switch and section of its route")
PLACE_COLUMNS = [
    ("resource_kind", pa.string(), "`node` (a switch) or `section` (a track piece, edge)"),
    ("resource_id", pa.string(), "node_id or edge_id"),
    ("interlocking", pa.string(), "interlocking controlling the resource"),
    ("track", pa.string(), "track name of the section, or of the switch"),
    ("station_id", pa.string(), "station the resource is named by: the one whose position (stations.parquet position_m) is nearest to the resource's extent from_m..to_m"),
    ("station_name", pa.string(), "name of that station"),
    ("station_distance_m", pa.float64(), "distance from the station's position to the nearer end of the resource's extent; 0 when the extent spans it [m]"),
    ("from_m", pa.float64(), "lower chainage of the resource [m]"),
    ("to_m", pa.float64(), "upper chainage of the resource [m]"),
]
"""Where a conflict or a headway is: the resource, and the station, track and km it is named by."""
CONFLICTS_SCHEMA = declare([
    ("conflict_id", pa.int32(), "conflict number, from 1 in time order; rows of one conflict share it"),
    ("train_a", pa.string(), "train that goes first by the decision"),
    ("train_b", pa.string(), "train that waits"),
    ("direction_a", pa.string(), "running direction of train_a"),
    ("direction_b", pa.string(), "running direction of train_b"),
    *PLACE_COLUMNS,
    ("a_start_s", pa.float64(), "train_a's window opens [s after midnight]"),
    ("a_end_s", pa.float64(), "train_a's window closes [s after midnight]"),
    ("b_start_s", pa.float64(), "train_b's window opens [s after midnight]"),
    ("b_end_s", pa.float64(), "train_b's window closes [s after midnight]"),
    ("overlap_start_s", pa.float64(), "start of the overlap of the two windows [s after midnight]"),
    ("overlap_end_s", pa.float64(), "end of the overlap [s after midnight]"),
    ("overlap_s", pa.float64(), "overlap of the two windows on this resource [s]"),
    ("headway_s", pa.float64(), "headway as planned: b_start_s − a_start_s, the time between the two fronts entering the resource (both windows open setting + approach before the entry) [s]"),
    ("min_headway_s", pa.float64(), "minimum headway: train_a's blocking time on the resource, a_end_s − a_start_s; train_b entering at least this much after train_a would not conflict here; min_headway_s − headway_s = a_end_s − b_start_s is the wait train_b needs on this resource [s]"),
    ("rule", pa.string(), "priority rule: `no-deadlock`, `timetable-order` or `leaves-first` (docs/design.md §8)"),
    ("decision", pa.string(), "who goes first and why"),
    ("delay_s", pa.float64(), "delay the decision imposes on train_b: shift that opens each of its windows after train_a's close [s]"),
    ("deadlock", pa.bool_(), "the two opposing trains would deadlock on a single-track stretch without the decision"),
    ("stretch", pa.string(), "for deadlocks: the single-track stretch first..last resource; else empty"),
], name="conflicts", description="Overlapping occupation windows of two trains, with the priority decision and the delay it causes")
HEADWAYS_SCHEMA = declare([
    *PLACE_COLUMNS,
    ("n_trains", pa.int32(), "trains whose route uses the resource"),
    ("train_a", pa.string(), "the earlier train of the tightest pair: of the trains whose window opens before train_b's, the one whose window closes last"),
    ("train_b", pa.string(), "the following train of the tightest pair (the smallest buffer_s on this resource)"),
    ("a_start_s", pa.float64(), "train_a's window opens [s after midnight]"),
    ("headway_s", pa.float64(), "headway as planned: train_b's window opens this long after train_a's, the time between the two fronts entering the resource [s]"),
    ("min_headway_s", pa.float64(), "minimum headway behind train_a: its blocking time on the resource (window close − open), the least headway at which train_b's window opens after train_a's closes [s]"),
    ("buffer_s", pa.float64(), "headway_s − min_headway_s: free time between train_a's window closing and train_b's opening; negative: they overlap by this much (a conflict) [s]"),
], name="headways", description="Minimum headway per switch and section: the tightest pair of following trains on each resource two or more trains use, its planned headway, minimum headway and buffer")

UNROUTED_SCHEMA = declare([
    ("train_id", pa.string(), "timetabled train that the track network cannot carry"),
    ("direction", pa.string(), "its running direction"),
    ("train_type", pa.string(), "its train type"),
    ("reason", pa.string(), "why: the stop it cannot reach, the node its route reaches nearest before that stop, and where the network goes from there"),
], name="unrouted", description="Trains the conflict check could not route on the track network: left out of the check (the others are checked as on a timetable without them) and flagged, never the end of the night")


@dataclass(frozen=True, eq=False)
class ConflictReport:
    """Everything the conflict check found for one line.

    ``conflicts``, ``occupation`` and ``headways`` are pandas DataFrames with
    the columns of :data:`CONFLICTS_SCHEMA`, :data:`OCCUPATION_SCHEMA` and
    :data:`HEADWAYS_SCHEMA` (plus ``line``, ``direction``, ``train_type``
    partition columns).
    """

    line_id: str
    params: BlockingParams
    routes: dict[str, Route]
    conflicts: Any
    occupation: Any
    summary: dict[str, Any] = field(default_factory=dict)
    headways: Any = None
    unrouted: Any = None
    """The ``unrouted`` dataset's frame (:data:`UNROUTED_SCHEMA`, plus ``line``): trains left out of the check."""

    def summary_lines(self) -> list[str]:
        s = self.summary
        out = [
            f"line {self.line_id}: {s['trains']} trains routed, {s['windows']} occupation windows "
            f"({s['loops']} loop stops for overtaking)",
            *unrouted_lines(self.unrouted),
            f"  conflicts: {_count(s['conflicts'], 'conflict')} between {_count(s['pairs'], 'train pair')} on "
            f"{_count(s['resources'], 'resource')}; deadlocks avoided: {s['deadlocks']}",
        ]
        for rule, n in sorted(s["by_rule"].items()):
            out.append(f"    {rule}: {n}")
        out.append(f"  delay imposed: total {s['delay_total_s']:.1f} s, largest {s['delay_max_s']:.1f} s"
                   + (f"; the {len(s['worst'])} largest (ties: the earliest), in time order:" if s["worst"] else ""))
        for row in s["worst"]:
            out.append(f"    {row}")
        if s.get("tightest"):
            out.append(f"  tightest headway: {s['tightest']}")
        for note in s["notes"]:
            out.append(f"  note: {note}")
        return out


UNROUTED_SHOWN = 5
"""How many unrouted trains a summary names (the ``unrouted`` dataset has them all)."""


def unrouted_lines(unrouted) -> list[str]:
    """The summary's lines for the trains the network cannot carry: a count, then the first few with why."""
    if unrouted is None or not len(unrouted):
        return []
    n = len(unrouted)
    out = [f"  not routed: {_count(n, 'train')} the track network cannot carry, left out of the check "
           "(the others are checked as without them):"]
    out += [f"    {r}" for r in unrouted["reason"].head(UNROUTED_SHOWN)]
    if n > UNROUTED_SHOWN:
        out.append(f"    … and {n - UNROUTED_SHOWN} more (the unrouted dataset)")
    return out


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def check_conflicts(line: Line, params: BlockingParams | Mapping[str, Any] | None = None, *,
                    curves: RunCurveSource | None = None,
                    progress: Callable[[int, int], None] | None = None,
                    curve_progress: Callable[[int, int], None] | None = None) -> ConflictReport:
    """Check a line's whole timetable for route conflicts (:func:`planner.network.check.check_timetable`, same
    parameters) and give the result as the datasets' frames."""
    return conflict_report(check_timetable(line, params, curves=curves, progress=progress,
                                           curve_progress=curve_progress))


def conflict_report(check: ConflictCheck, predicted: Windows | None = None) -> ConflictReport:
    """The frames of the ``conflicts``, ``occupation`` and ``headways`` datasets, and the summary, of a check;
    ``predicted``: the windows of the predicted day (:class:`planner.delay.predicted.PredictedDay`), in the
    check's order (none: the planned ones)."""
    records = check.conflicts
    conflicts = pd.DataFrame.from_records(records, columns=[f.name for f in CONFLICTS_SCHEMA] if not records else None)
    if len(conflicts):
        conflicts = conflicts[[f.name for f in CONFLICTS_SCHEMA]].sort_values(
            ["conflict_id", "from_m", "resource_kind", "resource_id"], kind="stable").reset_index(drop=True)
    conflicts.insert(0, "line", check.line_id)
    heads = pd.DataFrame.from_records(check.headways, columns=[f.name for f in HEADWAYS_SCHEMA])
    heads = heads.sort_values(["from_m", "to_m", "resource_kind", "resource_id"], kind="stable").reset_index(drop=True)
    heads.insert(0, "line", check.line_id)
    trains = list(check.trains)
    routes = [check.routes[t.train_id] for t in trains]
    occupation = _occupation_frame(check.graph, trains, routes, check.windows, check.params, check.line_id, predicted)
    summary = _summary(trains, routes, check.windows, conflicts, heads)
    summary["unrouted"] = len(check.unrouted)
    return ConflictReport(check.line_id, check.params, check.routes, conflicts, occupation, summary, heads,
                          unrouted_frame(check))


def unrouted_frame(check: ConflictCheck) -> pd.DataFrame:
    """The ``unrouted`` dataset's rows of a check, in timetable order."""
    names = ["line"] + [f.name for f in UNROUTED_SCHEMA]
    by_id = {t.train_id: t for t in check.graph.line.trains}
    rows = [(check.line_id, tid, by_id[tid].direction, by_id[tid].train_type, why)
            for tid, why in check.unrouted.items()]
    return pd.DataFrame.from_records(rows, columns=names)


def _occupation_frame(g: TrackGraph, trains, routes, w: Windows, p: BlockingParams, line_id: str,
                      predicted: Windows | None = None):
    pw = w if predicted is None else predicted
    tr = w.train
    kr = list(zip(w.kind.tolist(), w.res.tolist()))
    names = {x: (g.resource_id(*x), g.resource_interlocking(*x), g.resource_track(*x)) for x in set(kr)}
    rid = [names[x][0] for x in kr]
    il = [names[x][1] for x in kr]
    track = [names[x][2] for x in kr]
    # each window's rank by item within its train (ties in window order): one sort, not a pass per train
    order = np.lexsort((np.arange(len(w)), w.item, tr))
    tr_sorted = np.asarray(tr)[order]
    starts = np.flatnonzero(np.r_[True, tr_sorted[1:] != tr_sorted[:-1]])
    first = np.repeat(starts, np.diff(np.r_[starts, len(w)]))
    seq = np.zeros(len(w), dtype=np.int32)
    seq[order] = np.arange(len(w)) - first
    df = pd.DataFrame({
        "line": line_id,
        "direction": [trains[k].direction for k in tr],
        "train_type": [trains[k].train_type for k in tr],
        "train_id": [trains[k].train_id for k in tr],
        "seq": seq,
        "resource_kind": np.array(KIND_NAMES, dtype=object)[w.kind.astype(int)],
        "resource_id": rid,
        "interlocking": il,
        "track": track,
        "from_m": w.from_m, "to_m": w.to_m,
        "entry_s": w.entry_s, "exit_s": w.exit_s, "clear_s": w.clear_s,
        "setting_s": p.setting_s, "approach_s": p.approach_s,
        "running_s": w.exit_s - w.entry_s, "clearing_s": w.clear_s - w.exit_s,
        "release_s": p.release_s,
        "start_s": w.start_s, "end_s": w.end_s,
        "predicted_start_s": pw.start_s, "predicted_end_s": pw.end_s,
    })
    return df.sort_values(["train_id", "seq"], kind="stable").reset_index(drop=True)


def _summary(trains, routes, w: Windows, conflicts, headways=None) -> dict[str, Any]:
    notes = [f"train {r.train_id}: {n}" for r in routes for n in r.notes]
    s: dict[str, Any] = {
        "trains": len(trains), "windows": int(len(w)),
        "loops": sum(len(r.loop_calls) for r in routes), "notes": notes,
        "rows": int(len(conflicts)), "conflicts": 0, "pairs": 0, "resources": 0, "deadlocks": 0,
        "by_rule": {}, "delay_total_s": 0.0, "delay_max_s": 0.0, "worst": [], "tightest": "",
    }
    if len(conflicts):
        c = conflict_list(conflicts)
        s["conflicts"] = int(len(c))
        s["pairs"] = int(len(c.groupby(["train_a", "train_b"]).size()))  # ordered as decided: who went first
        s["resources"] = int(len(conflicts.groupby(["resource_kind", "resource_id"]).size()))
        s["deadlocks"] = int(c["deadlock"].sum())
        s["by_rule"] = {k: int(v) for k, v in c["rule"].value_counts().sort_index().items()}
        s["delay_total_s"] = float(c["delay_s"].sum())
        s["delay_max_s"] = float(c["delay_s"].max())
        s["worst"] = [
            f"#{cid}: {r.train_a} before {r.train_b} at {r.resource} ({r.place})"
            + (f" and {r.n - 1} more resource{'s' if r.n > 2 else ''}" if r.n > 1 else "")
            + f" ~{_hms(r.t0)}, overlap {r.overlap_s:.1f} s, delay {r.delay_s:.1f} s [{r.rule}]"
            for cid, r in largest(c, 5).iterrows()
        ]
    if headways is not None and len(headways):
        h = headways.sort_values(["buffer_s", "from_m"], kind="stable").iloc[0]
        s["tightest"] = (f"{h.resource_id} ({place_text(h)}): {h.train_b} {h.headway_s:.1f} s behind {h.train_a} "
                         f"~{_hms(h.a_start_s)}, minimum headway {h.min_headway_s:.1f} s, buffer {h.buffer_s:+.1f} s")
    return s


def _hms(t: float) -> str:
    t = int(round(t))
    return f"{t // 3600:02d}:{t // 60 % 60:02d}:{t % 60:02d}"


def place_text(r) -> str:
    """Where a resource is, as a planner says it: ``Takadai (TKD) track U1, km 11.100–11.405``.

    ``r`` has the ``station_*``, ``track``, ``from_m`` and ``to_m`` columns of the
    ``conflicts`` or ``headways`` dataset; a resource away from its station's
    position says how far (``1.2 km from Ohashi (OHS)``).
    """
    km = f"km {r.from_m / 1000:.3f}" + (f"–{r.to_m / 1000:.3f}" if r.to_m > r.from_m else "")
    d = float(r.station_distance_m)
    st = f"{r.station_name} ({r.station_id})"
    where = st if d < 0.5 else f"{d / 1000:.1f} km from {st}"
    return f"{where}{' track ' + str(r.track) if r.track else ''}, {km}"


def conflict_list(conflicts) -> pd.DataFrame:
    """One row per conflict (index ``conflict_id``) from the ``conflicts`` dataset's rows (one per resource).

    Columns: the pair, rule, decision, delay, deadlock; ``overlap_s`` (the
    largest on a resource), ``t0`` (first overlap), ``n`` (resources), the
    first resource (``resource``, ``interlocking``); ``headway_s`` and
    ``min_headway_s`` of the resource that needs the longest wait; where it is:
    ``place`` (:func:`place_text` of its first resource; km over every
    resource of it), ``station_id``, ``track``, ``from_m``, ``to_m``. The CLI,
    the margin report and the train graph list conflicts from this.
    """
    con = with_place(conflicts)
    c = con.groupby("conflict_id", sort=True).agg(
        train_a=("train_a", "first"), train_b=("train_b", "first"), rule=("rule", "first"),
        decision=("decision", "first"), delay_s=("delay_s", "first"), deadlock=("deadlock", "first"),
        overlap_s=("overlap_s", "max"), resource=("resource_id", "first"), interlocking=("interlocking", "first"),
        t0=("overlap_start_s", "min"), t1=("overlap_end_s", "max"), n=("resource_id", "size"),
        station_id=("station_id", "first"), station_name=("station_name", "first"),
        station_distance_m=("station_distance_m", "first"), track=("track", "first"),
        from_m=("from_m", "min"), to_m=("to_m", "max"))
    c["place"] = [place_text(r) for r in c.itertuples()]
    # headways of the resource that needs the longest wait (min_headway − headway largest): the one behind the delay
    need = con["min_headway_s"] - con["headway_s"]
    if need.notna().any():
        k = need.fillna(-np.inf).groupby(con["conflict_id"]).idxmax()
        c["headway_s"] = con.loc[k.to_numpy(), "headway_s"].to_numpy()
        c["min_headway_s"] = con.loc[k.to_numpy(), "min_headway_s"].to_numpy()
    else:
        c["headway_s"] = c["min_headway_s"] = np.nan
    return c


def largest(c: pd.DataFrame, n: int) -> pd.DataFrame:
    """The ``n`` largest delays of :func:`conflict_list`, listed in time order.

    Delays equal to the 0.1 s they are printed with are ties, and of tied
    conflicts the earliest are taken, so a day of identical conflicts lists its
    first ones (the morning), not whichever round-off made a few microseconds larger.
    """
    key = c.assign(_d=c["delay_s"].round(1))
    worst = key.sort_values(["_d", "t0"], ascending=[False, True], kind="stable").head(n)
    return worst.drop(columns="_d").sort_values("t0", kind="stable")


def with_place(conflicts) -> pd.DataFrame:
    """The rows with the place columns; a run written before they existed gets them empty."""
    con = conflicts
    missing = {"track": "", "station_id": "", "station_name": "", "station_distance_m": 0.0,
               "headway_s": np.nan, "min_headway_s": np.nan}
    if any(k not in con.columns for k in missing):
        con = con.assign(**{k: v for k, v in missing.items() if k not in con.columns})
    return con


def conflicts_table(line: Line, params: BlockingParams | Mapping[str, Any] | None = None, *,
                    curves: RunCurveSource | None = None):
    """The conflicts table of a line, for reports (the margin HTML report calls this).

    Returns an empty DataFrame (with the columns) when the line has no track
    network.
    """
    if line.network is None:
        return pd.DataFrame(columns=["line"] + [f.name for f in CONFLICTS_SCHEMA])
    return check_conflicts(line, params, curves=curves).conflicts


def write_conflicts(report: ConflictReport, out_dir) -> list:
    """Write ``conflicts``, ``headways``, ``unrouted`` and ``occupation`` datasets under ``out_dir`` (hive-partitioned,
    atomic): :func:`write_conflict_tables` and :func:`write_occupation`."""
    return (write_conflict_tables(report.line_id, report.conflicts, report.headways, report.unrouted, out_dir)
            + write_occupation(report.occupation, out_dir))


def write_conflict_tables(line_id: str, con, heads, unrouted, out_dir) -> list:
    """Write the line's ``conflicts``, ``headways`` and ``unrouted`` datasets, one file each:
    ``conflicts/line=L/part-0.parquet`` and so on (a conflict or a resource can involve both directions, so they
    are partitioned by line only); an empty file where there are no rows, so readers find the schema."""
    out = Path(out_dir)
    written = []
    lid = check_path_id(line_id, "line id ")
    if len(con):
        written += write_partitioned(pa.Table.from_pandas(con, preserve_index=False), out, "conflicts",
                                     ("line",), schema=CONFLICTS_SCHEMA,
                                     sort_by=("conflict_id", "from_m", "resource_kind", "resource_id"))
    else:  # an empty file, so readers find the dataset and its schema
        path = out / "conflicts" / f"line={lid}" / "part-0.parquet"
        write_parquet_atomic(CONFLICTS_SCHEMA.empty_table(), path)
        written.append(path)
    if heads is not None:
        if len(heads):
            written += write_partitioned(pa.Table.from_pandas(heads, preserve_index=False), out, "headways",
                                         ("line",), schema=HEADWAYS_SCHEMA,
                                         sort_by=("from_m", "to_m", "resource_kind", "resource_id"))
        else:
            path = out / "headways" / f"line={lid}" / "part-0.parquet"
            write_parquet_atomic(HEADWAYS_SCHEMA.empty_table(), path)
            written.append(path)
    unrouted = unrouted if unrouted is not None else pd.DataFrame(columns=["line"])
    path = out / "unrouted" / f"line={lid}" / "part-0.parquet"  # always: readers find its schema
    table = (pa.Table.from_pandas(unrouted.drop(columns=["line"]), preserve_index=False, schema=UNROUTED_SCHEMA)
             if len(unrouted) else UNROUTED_SCHEMA.empty_table())
    write_parquet_atomic(table, path)
    written.append(path)
    return written


def write_occupation(occ, out_dir, part: str = "0") -> list:
    """Write the ``occupation`` dataset's rows: ``occupation/line=L/direction=D/train_type=T/part-<part>.parquet``
    (a line checked in sections writes one part per section, :mod:`planner.network.sections`)."""
    if not len(occ):
        return []
    return write_partitioned(pa.Table.from_pandas(occ, preserve_index=False), Path(out_dir), "occupation",
                             schema=OCCUPATION_SCHEMA, sort_by=("train_id", "seq"), part=part)


def read_occupation_part(out, line_id: str, part: str, columns: list[str]) -> pd.DataFrame | None:
    """A line's part ``part`` of the ``occupation`` dataset (a section's windows, :func:`write_occupation`),
    ``columns`` only, its partitions' files in their folders' order; None when the part has no windows."""
    import pyarrow.parquet as pq

    folder = Path(out) / "occupation" / f"line={check_path_id(line_id, 'line id ')}"
    files = sorted(folder.glob(f"*/*/part-{check_path_id(part, 'part ')}.parquet"))
    if not files:
        return None
    return pa.concat_tables([pq.read_table(f, columns=columns) for f in files]).to_pandas()


def renumbered(parts) -> pd.DataFrame:
    """The conflicts tables of a line's sections as one, numbered from 1 in time order across them, as the whole
    line's check numbers them: by each conflict's earliest window opening of the two trains, then the pair, then
    (within a section, where the check numbered them in this same order) its number there."""
    parts = [c for c in parts if len(c)]
    if not parts:
        return pd.DataFrame(columns=["line"] + [f.name for f in CONFLICTS_SCHEMA])
    if len(parts) == 1:
        return parts[0]
    # every row of every part at once (a sort per section was 2.5 s of the job process on the 100x line): a conflict
    # of a part is placed by its earliest row in the order (t0, a, b), the conflicts in the order (t0, a, b, part, cid)
    sizes = [len(c) for c in parts]
    part = np.repeat(np.arange(len(parts)), sizes)
    cid = np.concatenate([c["conflict_id"].to_numpy(np.int64) for c in parts])
    rows = pd.DataFrame({
        "t0": np.concatenate([np.minimum(c["a_start_s"].to_numpy(float), c["b_start_s"].to_numpy(float))
                              for c in parts]),
        "a": np.concatenate([c["train_a"].to_numpy() for c in parts]),
        "b": np.concatenate([c["train_b"].to_numpy() for c in parts]),
        "part": part, "cid": cid})
    first = rows.sort_values(["t0", "a", "b", "part", "cid"], kind="stable").drop_duplicates(["part", "cid"])
    low = int(cid.min())
    span = int(cid.max()) - low + 1
    placed = first["part"].to_numpy(np.int64) * span + (first["cid"].to_numpy(np.int64) - low)  # in their order
    order = np.argsort(placed, kind="stable")
    at = np.searchsorted(placed[order], part.astype(np.int64) * span + (cid - low))  # each row's conflict
    number = order[at] + 1
    out, start = [], 0
    for c, n in zip(parts, sizes):
        c = c.copy()
        c["conflict_id"] = number[start:start + n].astype(np.int64)
        out.append(c)
        start += n
    return pd.concat(out, ignore_index=True).sort_values(
        ["conflict_id", "from_m", "resource_kind", "resource_id"], kind="stable").reset_index(drop=True)
