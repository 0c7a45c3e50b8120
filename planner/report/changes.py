"""What changed between two runs: inputs (line tables, job parameters, code) and what that did to the outputs.

:func:`compare_runs` reads two published run folders and lists, per line:

* **inputs** — the code version (``code_digest``, planner version), every job
  parameter whose value differs, and for the line database every row of every
  table that was added, removed or changed (a run keeps a copy of its line
  tables under ``inputs/<line_id>/``, checked against the line's
  ``source_digest`` in the manifest before it is read); and the operating
  days' own inputs (the manifests' ``operating_day``): each temporary
  restriction that came into force, was lifted or changed, and each train that
  runs on one day and not on the other;
* **legs** — margin rows (stop → next stop, train type, direction, scheduled
  time) whose minimum running time, margin or bad-day margin moved by more
  than ``threshold_s``, or that appeared or disappeared; each is traced to the
  line-table changes that lie within one train length of its stretch (or name
  its train type or trains), which is how the page says "this restriction made
  these legs this much slower";
* **flags** — legs whose ``impossible``, ``short_bad_day``, ``tight``,
  ``unreachable``, ``inaccurate`` or ``unassessed`` flag appeared or cleared
  (a margin going from 7.1 s to −0.5 s: *impossible* appeared, whatever the
  bad day did), and conflicts (train pair, resource) that appeared or cleared;
* **bundles** — bundles whose content changed (:mod:`planner.report.bundle_changes`): members whose SHA-256 differs,
  with the rows that differ and the bytes, after both bundles verified against
  their own run's public key.

The result is one table (the ``changes`` dataset, :data:`CHANGES_SCHEMA`) and
an HTML section (:func:`planner.pages.changes.changes_html`) that the nightly
job puts at the top of the margin report. ``planner diff RUN_A RUN_B`` prints the same.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import pyarrow as pa

from planner.errors import InputError
from planner.io.parquet import declare
from planner.report.bundle_changes import bundle_changes
from planner.report.leg_flags import FLAG
from planner.report.margin_rule import TIME_TOL_S
from planner.line.units import shown
from planner.report.published_run import line_inputs, path_id, read_line_dataset, read_manifest

THRESHOLD_S = 0.5
"""A leg's minimum or margin must move by more than this to be listed [s] (tables are exact to ~0.05 s)."""

TABLE_KEYS: dict[str, tuple[str, ...]] = {
    "line": ("line_id",),
    "stations": ("station_id",),
    "gradients": ("start_m", "end_m"),
    "curves": ("start_m", "end_m"),
    "speed_limits": ("start_m", "end_m", "direction", "train_type", "kind"),
    "beacons": ("beacon_id",),
    "signals": ("signal_id",),
    "rolling_stock": ("train_type",),
    "traction": ("train_type", "speed_kmh"),
    "timetable": ("train_id", "seq"),
    "nodes": ("node_id",),
    "edges": ("edge_id",),
}
"""Columns that identify a row of each line table: a row with the same key but other values is *changed*."""

LEG_KEY = ("direction", "train_type", "origin", "destination", "scheduled_running_time_s")
LEG_MEASURES = ("min_running_time_s", "margin_s", "remaining_margin_s")
LEG_FLAGS = ("impossible", "short_bad_day", "tight", "unreachable", "inaccurate", "unassessed")
"""The flags of a leg compared between runs (``infeasible`` is the first two together: not listed twice)."""

CATEGORIES = ("code", "parameter", "line_table", "restriction", "train", "leg", "flag", "conflict", "bundle")
INPUTS = CATEGORIES[:5]
"""The categories of input changes: what a moved leg is traced to."""

CHANGES_SCHEMA = declare([
    ("base_run", pa.string(), "run this one is compared with (the previous published run)"),
    ("change_id", pa.int32(), "number of the change within the line, from 0"),
    ("category", pa.string(), "`code`, `parameter`, `line_table`, `restriction` (a temporary restriction that came into force, was lifted or changed between the two runs' operating days), `train` (a train that runs on one day and not on the other) (inputs); `leg`, `flag`, `conflict`, `bundle` (outputs)"),
    ("subject", pa.string(), "what changed: parameter key, table name, leg, flag, conflict or bundle file"),
    ("field", pa.string(), "column or measure that changed (its unit is in its name); `row` for a whole row"),
    ("before", pa.string(), "value in the base run, as text (empty: did not exist)"),
    ("after", pa.string(), "value in this run, as text (empty: no longer exists)"),
    ("delta", pa.float64(), "after − before for numbers, in the unit of `field`; null otherwise"),
    ("detail", pa.string(), "the change in one sentence"),
    ("direction", pa.string(), "running direction of a leg or bundle; null otherwise"),
    ("train_type", pa.string(), "train type of a leg or bundle; null otherwise"),
    ("origin", pa.string(), "departure stop (station id) of a leg or flag row, as in margins; null otherwise"),
    ("destination", pa.string(), "next stop (station id) of a leg or flag row, as in margins; null otherwise"),
    ("train_id", pa.string(), "the train of a timetable row, or the train that waits in a conflict (train_b); "
                              "null otherwise"),
    ("from_m", pa.float64(), "lower chainage of a line-table change or a leg [m]; null when it has none"),
    ("to_m", pa.float64(), "upper chainage [m]; null when it has none"),
    ("caused_by", pa.list_(pa.int32()), "change_ids of the input changes that reach this leg (within a train length of its stretch, or naming its train type or trains)"),
], name="changes", version=2, description="What changed since the previous run: inputs (code, job parameters, line-table rows) and outputs (legs whose minimum or margin moved, flags, conflicts, bundles)")


@dataclass
class LineChanges:
    """Changes of one line between two runs; ``rows`` are dicts with the columns of :data:`CHANGES_SCHEMA`."""

    line_id: str
    base_run: str
    run: str
    threshold_s: float = THRESHOLD_S
    rows: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def add(self, category: str, subject: str, detail: str, *, field_: str = "", before: Any = "", after: Any = "",
            delta: float | None = None, direction: str | None = None, train_type: str | None = None,
            from_m: float | None = None, to_m: float | None = None, caused_by: Iterable[int] = (),
            origin: str | None = None, destination: str | None = None, train_id: str | None = None) -> int:
        cid = len(self.rows)
        self.rows.append({
            "base_run": self.base_run, "change_id": cid, "category": category,
            "subject": subject, "field": field_, "before": _text(before), "after": _text(after),
            "delta": None if delta is None or not math.isfinite(delta) else float(delta), "detail": detail,
            "direction": direction, "train_type": train_type, "origin": origin, "destination": destination,
            "train_id": train_id, "from_m": from_m, "to_m": to_m, "caused_by": [int(c) for c in caused_by],
        })
        return cid

    def extend(self, rows: Iterable[dict[str, Any]]) -> None:
        """Append rows another comparison of the same line made (the bundles', on the worker that built them): each
        renumbered after this one's and named by this one's base run. Only rows that name no other change
        (``caused_by`` empty, as the bundles' rows are) can move between comparisons."""
        for r in rows:
            if r["caused_by"]:
                raise ValueError(f"change {r['change_id']} names other changes: it cannot be renumbered")
            self.rows.append({**r, "base_run": self.base_run, "change_id": len(self.rows)})

    def of(self, *categories: str) -> list[dict[str, Any]]:
        return [r for r in self.rows if r["category"] in categories]

    def table(self) -> pa.Table:
        """The rows as a pyarrow table with the ``line`` column (for the hive-partitioned dataset)."""
        cols = {f.name: [r[f.name] for r in self.rows] for f in CHANGES_SCHEMA}
        t = pa.Table.from_pydict(cols, schema=CHANGES_SCHEMA)
        return t.append_column("line", pa.array([self.line_id] * len(self.rows), pa.string()))

    def summary_lines(self) -> list[str]:
        """What ``planner diff`` prints: a count per category, then one line per input change and per leg (every
        measure and flag of a leg on its line, not one line each), with the input changes that moved it."""
        n = {c: len(self.of(c)) for c in CATEGORIES}
        out = [f"line {self.line_id}: {self.run} against {self.base_run}: "
               + (", ".join(f"{v} {k}" for k, v in n.items() if v) or "no changes")]
        by_id = {r["change_id"]: r for r in self.rows}
        groups: dict[tuple, list] = {}
        for r in self.rows:
            if r["category"] in ("leg", "flag"):
                key = ("leg", r["subject"])
            elif r["category"] == "conflict":  # one line per place and way: the conflicts of a clock-face timetable
                key = ("conflict", (r["subject"].split(" at ", 1)[1], r["after"] != ""))
            else:
                key = ("", r["change_id"])
            groups.setdefault(key, []).append(r)
        for (kind, subject), rows in groups.items():
            if not kind or len(rows) == 1 and kind == "conflict":
                out.append(f"  [{rows[0]['category']}] {rows[0]['detail']}")
                continue
            if kind == "conflict":
                first = rows[0]["detail"]
                place = first[first.index(" at ") + 4:first.rindex(" appeared" if subject[1] else " cleared")]
                pairs = [f"{b} waits {_num(r['after'] or r['before']):.1f} s for {a}"
                         for r in rows for a, b in [r["subject"].split(" at ")[0].split("/", 1)]]
                out.append(f"  [conflict] {len(rows)} conflicts {'appeared' if subject[1] else 'cleared'} at {place}: "
                           + ", ".join(pairs[:6]) + (f" and {len(pairs) - 6} more" if len(pairs) > 6 else ""))
                continue
            prefix = f"leg {subject}"
            bits = [r["detail"][len(prefix):].lstrip(": ") if r["detail"].startswith(prefix) else r["detail"]
                    for r in rows]
            causes = sorted({c for r in rows for c in r["caused_by"]})
            why = ("; after " + ", ".join(_cause(by_id[c]) for c in causes[:3])
                   + (f" and {len(causes) - 3} more" if len(causes) > 3 else "")) if causes else ""
            out.append(f"  [leg] {subject}: {'; '.join(bits)}{why}")
        out += [f"  note: {x}" for x in self.notes]
        return out


def _cause(r: dict) -> str:
    """An input change named in a few words: ``restriction TSR-1 (#4)``, ``speed_limits row (#2)``."""
    what = {"restriction": f"restriction {r['subject']}", "train": f"train {r['subject']}",
            "line_table": f"{r['subject']} change", "parameter": f"parameter {r['subject']}"}.get(
        r["category"], r["category"])
    return f"{what} (#{r['change_id']})"


def _text(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        return f"{v:g}" if abs(v) >= 1e-3 or v == 0 else repr(v)
    if isinstance(v, (list, tuple, np.ndarray)):
        return json.dumps([_plain(x) for x in v], ensure_ascii=False)
    return str(_plain(v))


def _plain(x):
    """A dataset value as plain Python: numpy scalars become numbers and list columns (numpy arrays
    after ``to_pandas``) become lists, so a row's values can be tested for truth, compared and
    joined like any other (an array's truth value is ambiguous)."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


def _num(v) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return float("nan")
    return f


# ---------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------
def _flatten(d: Any, prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    if isinstance(d, dict):
        for k in sorted(d):
            out.update(_flatten(d[k], f"{prefix}.{k}" if prefix else str(k)))
    else:
        out[prefix] = d
    return out


def _row_text(table: str, row: dict[str, Any]) -> str:
    """A line-table row in words, e.g. ``5000–5150 m both civil 85 km/h``."""
    if table == "speed_limits":
        tt = row.get("train_type")
        return (f"speed restriction {_text(row.get('start_m'))}–{_text(row.get('end_m'))} m "
                f"{row.get('direction')}{'' if tt in (None, '') or (isinstance(tt, float) and math.isnan(tt)) else ' ' + str(tt)} "
                f"{row.get('kind')}")
    key = TABLE_KEYS.get(table)
    if key and all(k in row for k in key):
        return f"{table} " + " ".join(_text(row[k]) for k in key)
    return f"{table} row"


def _extent(table: str, row: dict[str, Any]) -> tuple[float, float] | None:
    if "start_m" in row and "end_m" in row and table in ("gradients", "curves", "speed_limits", "line"):
        return float(row["start_m"]), float(row["end_m"])
    for c in ("position_m",):
        if c in row and row[c] is not None and math.isfinite(_num(row[c])):
            lo, hi = _num(row[c]), _num(row[c])
            for s in ("stop_down_m", "stop_up_m"):
                if s in row:
                    lo, hi = min(lo, _num(row[s])), max(hi, _num(row[s]))
            return lo, hi
    return None


def _cell(v, boxed: bool):
    """One value of a row as :func:`_records` gives it; ``boxed``: of a column ``to_dict`` boxes."""
    if boxed:
        import pandas as pd

        if v is pd.NA:
            return None
        if isinstance(v, np.datetime64):
            return pd.Timestamp(v)
        if isinstance(v, np.timedelta64):
            return pd.Timedelta(v)
    return None if isinstance(v, float) and math.isnan(v) else _plain(v)


def _records(df) -> list[dict[str, Any]]:
    """Each row as a dict of plain Python values (:func:`_plain`), NaN as None, as ``df.to_dict("records")`` gives
    them. Made a column at a time: a numpy column of numbers or truth values is one ``tolist`` (Python numbers, as
    ``to_dict`` boxes them), so only the other columns take a call per value (a 100x line's margins are 7,400 rows
    of 59 columns). ``tolist`` gives the values iterating the column would, made at once."""
    cols = []
    for name in df.columns:
        col = df[name]
        if isinstance(col.dtype, np.dtype) and col.dtype.kind in "fiub":  # numpy's own: no NA of pandas or Arrow
            vals = col.to_numpy().tolist()
            cols.append([None if v != v else v for v in vals] if col.dtype.kind == "f" else vals)
        else:  # to_dict boxes the values of object and extension columns: NA as None, numpy times as pandas'
            boxed = col.dtype == object or not isinstance(col.dtype, np.dtype)
            cols.append([v if type(v) is str else _cell(v, boxed) for v in col.tolist()])
    names = list(df.columns)
    return [dict(zip(names, row)) for row in zip(*cols)] if names else [{} for _ in range(len(df))]


def _canon(v):
    if isinstance(v, float):
        return None if math.isnan(v) else round(v, 9)
    if isinstance(v, (list, tuple, np.ndarray)):
        return tuple(_canon(x) for x in v)
    return v


def diff_table(name: str, old, new) -> list[tuple[str, dict | None, dict | None, list[str]]]:
    """Rows added, removed or changed between two versions of a line table.

    Returns
    -------
    list of (kind, old_row, new_row, changed_columns)
        kind is ``changed`` (same key, other values), ``added`` or ``removed``;
        in table order of the new (then old) version.
    """
    old_r, new_r = _records(old), _records(new)
    cols = [c for c in new.columns if c in set(old.columns)]
    key = [k for k in TABLE_KEYS.get(name, ()) if k in cols]
    sig = lambda r: tuple(_canon(r.get(c)) for c in sorted(set(r)))  # noqa: E731
    old_sigs = {}
    for r in old_r:
        old_sigs.setdefault(sig(r), []).append(r)
    new_sigs = {}
    for r in new_r:
        new_sigs.setdefault(sig(r), []).append(r)
    gone = [r for s, rs in old_sigs.items() for r in rs[len(new_sigs.get(s, [])):]]
    came = [r for s, rs in new_sigs.items() for r in rs[len(old_sigs.get(s, [])):]]
    out = []
    if key:
        kf = lambda r: tuple(_canon(r.get(k)) for k in key)  # noqa: E731
        gone_by = {}
        for r in gone:
            gone_by.setdefault(kf(r), []).append(r)
        for r in came:
            lst = gone_by.get(kf(r))
            if lst:
                o = lst.pop(0)
                changed = [c for c in sorted(set(o) | set(r)) if _canon(o.get(c)) != _canon(r.get(c))]
                out.append(("changed", o, r, changed))
            else:
                out.append(("added", None, r, []))
        for lst in gone_by.values():
            out += [("removed", o, None, []) for o in lst]
    else:
        out += [("added", None, r, []) for r in came] + [("removed", o, None, []) for o in gone]
    return out


def _str(v) -> str | None:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    return str(v)


# ---------------------------------------------------------------------------
# Outputs
# ---------------------------------------------------------------------------
def _lifted(r) -> str:
    return r.get("_lifted", "")


def _legs_by_key(frame) -> dict[tuple, dict]:
    """Margins rows by :data:`LEG_KEY`. A leg × scheduled time with a row of its own for the trains that pass
    while some of the day's restrictions are lifted (fewer ``restrictions``) keys that row by what it lacks
    too, so the row of the trains that meet every restriction compares with the leg's row of another day."""
    recs = _records(frame)
    keys = [tuple(_canon(v) for v in k) for k in frame[list(LEG_KEY)].itertuples(index=False, name=None)]
    if "restrictions" not in frame.columns:
        return dict(zip(keys, recs))
    sets = [set(r["restrictions"] or ()) for r in recs]
    full: dict[tuple, set] = {}
    for k, got in zip(keys, sets):
        full[k] = full.get(k, set()) | got
    out = {}
    for k, got, r in zip(keys, sets, recs):
        off = ", ".join(sorted(full[k] - got))
        out[k + (f"without {off}",) if off else k] = {**r, "_lifted": off}
    return out


def _leg_label(r) -> str:
    via = f" via {len(r['passes'])} passes" if r.get("passes") is not None and len(r["passes"]) else ""
    sched = _num(r.get("scheduled_running_time_s"))
    off = f", trains passing without {_lifted(r)}" if _lifted(r) else ""
    return (f"{r['train_type']} {r['direction']} {r['origin']}→{r['destination']}{via} "
            + (f"(scheduled {sched:g} s{off})" if math.isfinite(sched) else "(not timetabled)"))


def _causes(reach: dict[int, dict], r: dict, lo: float, hi: float, length_m: float) -> list[int]:
    out = []
    for cid, sc in reach.items():
        if sc.get("direction") not in (None, "both", r["direction"]):
            continue
        if sc.get("train_type") not in (None, "") and sc["train_type"] != r["train_type"]:
            continue
        if sc.get("train_id") is not None:
            if sc["train_id"] in set(r.get("train_ids") or ()):
                out.append(cid)
            continue
        ext = sc.get("extent")
        if sc.get("all") or ext is None:
            if sc.get("train_type") or sc.get("all"):
                out.append(cid)
            continue
        if ext[1] >= lo - length_m and ext[0] <= hi + length_m:
            out.append(cid)
    return out


def _leg_changes(ch: LineChanges, old, new, reach: dict[int, dict], threshold_s: float, geometry) -> None:
    """Legs whose minimum or margins moved by more than the threshold, and flags that appeared or cleared."""
    if old is None or new is None:
        ch.notes.append("margins not in both runs: legs not compared")
        return
    o, n = _legs_by_key(old), _legs_by_key(new)
    for k in sorted(set(o) | set(n), key=lambda k: tuple(str(x) for x in k)):
        a, b = o.get(k), n.get(k)
        moved, flipped = [], []
        if a is not None and b is not None:
            for m in LEG_MEASURES:
                va, vb = _num(a.get(m)), _num(b.get(m))
                if math.isfinite(va) and math.isfinite(vb) and abs(vb - va) > threshold_s:
                    moved.append((m, va, vb))
            for f in LEG_FLAGS:
                fa, fb = _flag(a, f), _flag(b, f)
                if fa is not None and fb is not None and fa != fb:
                    flipped.append((f, fa, fb))
            if not (moved or flipped):  # most legs of a night: nothing to place or trace
                continue
        r = b or a
        label = _leg_label(r)
        lo, hi, length = geometry(r)
        causes = _causes(reach, r, lo, hi, length) if lo is not None else []
        common = dict(direction=r["direction"], train_type=r["train_type"], origin=_str(r["origin"]),
                      destination=_str(r["destination"]), from_m=lo, to_m=hi, caused_by=causes)
        if a is None or b is None:
            ch.add("leg", label, f"leg {label} {'appeared' if b else 'disappeared'}", field_="row",
                   before="" if b else label, after=label if b else "", **common)
            continue
        for m, va, vb in moved:
            ch.add("leg", label, f"leg {label}: {m} {shown(va)} → {shown(vb)} s ({vb - va:+.1f} s)", field_=m,
                   before=round(va, 3), after=round(vb, 3), delta=vb - va, **common)
        for f, fa, fb in flipped:
            ch.add("flag", label, f"leg {label}: {FLAG[f].badge} {'appeared' if fb else 'cleared'} "
                   f"({_flag_measure(f, a, b)})", field_=f, before=fa, after=fb, **common)


def _flag(r: dict, f: str) -> bool | None:
    """A leg's flag in a run; a run from before ``impossible`` and ``short_bad_day`` has them derived from its
    ``margin_s`` and ``infeasible`` (the same definitions); None: unknown, or no such flag in the run (not
    compared)."""
    if f in r:  # null: unknown on an unassessed leg, whose own flag says so
        return None if r[f] is None else bool(r[f])
    if f in ("impossible", "short_bad_day") and "infeasible" in r:
        impossible = _num(r.get("margin_s")) < -TIME_TOL_S
        return impossible if f == "impossible" else bool(r["infeasible"]) and not impossible
    return None


def _flag_measure(f: str, a: dict, b: dict) -> str:
    """The number behind a flag before and after, e.g. ``margin 7.1 → -0.5 s``."""
    m, word = {"impossible": ("margin_s", "margin"), "unreachable": ("margin_s", "margin"),
               "inaccurate": ("closed_loop_max_error_s", "closed-loop error")}.get(
        f, ("remaining_margin_s", "bad-day margin"))
    return f"{word} {shown(_num(a.get(m)))} → {shown(_num(b.get(m)))} s"


def _conflict_changes(ch: LineChanges, old, new) -> None:
    if old is None or new is None:
        return
    import pandas as pd

    from planner.datasets.conflicts import place_text
    def keys(df):
        out = {}
        for r in _records(df):
            out.setdefault((r["train_a"], r["train_b"], r["resource_id"]), r)
        return out
    o, n = keys(old), keys(new)
    for k in sorted(set(o) ^ set(n)):
        r = n.get(k) or o[k]
        appeared = k in n
        where = f" ({place_text(pd.Series(r))})" if r.get("station_id") else ""
        ch.add("conflict", f"{k[0]}/{k[1]} at {k[2]}",
               f"conflict {k[0]} before {k[1]} at {k[2]}{where} {'appeared' if appeared else 'cleared'} "
               f"(delay {_num(r.get('delay_s')):.1f} s, {r.get('rule')})",
               field_="delay_s", before="" if appeared else r.get("delay_s"), after=r.get("delay_s") if appeared else "",
               direction=r.get("direction_b"), train_id=_str(k[1]), from_m=r.get("from_m"), to_m=r.get("to_m"))


def compare_runs(old_dir: str | Path, new_dir: str | Path, *, threshold_s: float = THRESHOLD_S,
                 lines: Iterable[str] | None = None, new_manifest: dict | None = None,
                 bundles: bool = True) -> list[LineChanges]:
    """Compare two published runs, line by line (module doc for what is compared).

    Parameters
    ----------
    old_dir, new_dir : path
        Run folders (``outputs/r0006-…``, ``outputs/r0007-…``); ``new_dir`` may
        also be a staging folder holding a manifest.
    threshold_s : float
        Legs whose minimum running time, margin or bad-day margin moved by
        more than this are listed [s].
    lines : iterable of str, optional
        Line ids to compare (default: every line of the newer run).
    new_manifest : dict, optional
        The newer run's manifest, or the part of it that the comparison reads (:func:`planner.job.pipeline.
        manifest_head`: the nightly job compares a line before its run's manifest is written); default: read
        from ``new_dir``.
    bundles : bool
        Compare the bundles too (:func:`planner.report.bundle_changes.bundle_changes`); the nightly job compares
        them on the worker that built them and adds their rows (:meth:`LineChanges.extend`).
    """
    if not (isinstance(threshold_s, (int, float)) and threshold_s >= 0):
        raise InputError(f"--threshold-s must be a number ≥ 0, found {threshold_s!r}")
    from planner.report.input_changes import day_input_changes, input_changes

    old_dir, new_dir = Path(old_dir), Path(new_dir)
    om, nm = read_manifest(old_dir), new_manifest if new_manifest is not None else read_manifest(new_dir)
    ids = list(lines) if lines is not None else [x["line_id"] for x in nm.get("lines", [])]
    out = []
    for lid in ids:
        ch = LineChanges(lid, str(om["run_id"]), str(nm["run_id"]), float(threshold_s))
        reach = input_changes(ch, old_dir, om, new_dir, nm)
        reach.update(day_input_changes(ch, om, nm))
        geometry = _geometry(new_dir, nm, lid)
        _leg_changes(ch, read_line_dataset(old_dir, "margins", lid), read_line_dataset(new_dir, "margins", lid),
                     reach, threshold_s, geometry)
        _conflict_changes(ch, read_line_dataset(old_dir, "conflicts", lid),
                          read_line_dataset(new_dir, "conflicts", lid))
        if bundles:
            bundle_changes(ch, old_dir, new_dir)
        out.append(ch)
    return out


def _geometry(run_dir: Path, manifest: dict, line_id: str):
    """Function leg row → (lower, upper chainage of its stop markers, train length) from the run's line copy."""
    folder = line_inputs(run_dir, manifest, line_id)
    if folder is None:
        return lambda r: (None, None, 0.0)
    import pyarrow.parquet as pq

    st = pq.read_table(folder / "stations.parquet").to_pandas().set_index("station_id")
    rs = pq.read_table(folder / "rolling_stock.parquet").to_pandas().set_index("train_type")

    def geo(r):
        col = "stop_down_m" if r["direction"] == "down" else "stop_up_m"
        try:
            a, b = float(st.loc[r["origin"], col]), float(st.loc[r["destination"], col])
            length = float(rs.loc[r["train_type"], "length_m"])
        except KeyError:
            return None, None, 0.0
        return min(a, b), max(a, b), length
    return geo


def write_changes(changes: LineChanges, out_dir: str | Path) -> list[Path]:
    """Write ``changes/line=L/part-0.parquet`` (an empty file when nothing changed, so readers find the schema)."""
    from planner.io.parquet import write_parquet_atomic

    path = Path(out_dir) / "changes" / f"line={path_id(changes.line_id)}" / "part-0.parquet"
    t = changes.table().drop_columns(["line"])
    write_parquet_atomic(t.cast(CHANGES_SCHEMA), path)
    return [path]
