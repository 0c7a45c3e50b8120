"""The job's ``[robustness]``: its rules read and checked, and the day as it will run computed from a conflict check.

Takes the job's :class:`~planner.job.config.RobustnessSection` (primary delays, minimum dwell, connections,
days and seed) and a line's conflict check; gives the predicted day, the statistics of the simulated days and
the summary the page and the CLI print (:func:`day_as_it_runs`): the one path the nightly job (on the worker
of the line's conflict check) and ``planner robustness`` both take.
"""
from __future__ import annotations

import hashlib
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from planner.errors import InputError, JobError
from planner.delay.primary import DISTRIBUTIONS, KINDS, Rule

_DELAY_KEYS = {"kind", "distribution", "train_type", "probability", "mean_s", "file"}
_DWELL_KEYS = {"station_id", "train_type", "min_dwell_s"}
EMPIRICAL_COLUMNS = ("delay_s", "kind", "train_type")
"""Columns of an empirical delay file: ``delay_s`` (observed delay [s], ≥ 0; required); ``kind`` and ``train_type``
(optional: only the rows of the rule's kind and train type are used)."""


def _number(where: str, v: Any, lo: float, hi: float) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo <= float(v) <= hi):
        raise JobError(f"{where}: expected a number in [{lo:g}, {hi:g}], found {v!r}")
    return float(v)


def parse_tables(where: str, key: str, value: Any) -> tuple:
    """``[robustness] delays`` or ``min_dwell``: a list of tables, each checked (raises JobError naming the item)."""
    if not isinstance(value, list) or not all(isinstance(x, dict) for x in value):
        raise JobError(f"{where}: expected a list of tables, e.g. [{{ kind = \"origin\", distribution = "
                       f"\"exponential\", probability = 0.3, mean_s = 60.0 }}]")
    out = []
    for i, item in enumerate(value):
        w = f"{where}[{i}]"
        known = _DELAY_KEYS if key == "delays" else _DWELL_KEYS
        extra = sorted(set(item) - known)
        if extra:
            raise JobError(f"{w}: unknown key {extra[0]!r}; known keys: {', '.join(sorted(known))}")
        if not isinstance(item.get("train_type", "*"), str):
            raise JobError(f"{w} train_type: expected a train type name or \"*\"")
        if key == "min_dwell":
            if not isinstance(item.get("station_id", "*"), str):
                raise JobError(f"{w} station_id: expected a station id or \"*\"")
            out.append({"station_id": item.get("station_id", "*"), "train_type": item.get("train_type", "*"),
                        "min_dwell_s": _number(f"{w} min_dwell_s", item.get("min_dwell_s"), 0.0, 3600.0)})
            continue
        kind, dist = item.get("kind"), item.get("distribution", "exponential")
        if kind not in KINDS:
            raise JobError(f"{w} kind: one of {', '.join(KINDS)}, found {kind!r}")
        if dist not in DISTRIBUTIONS:
            raise JobError(f"{w} distribution: one of {', '.join(DISTRIBUTIONS)}, found {dist!r}")
        d = {"kind": kind, "distribution": dist, "train_type": item.get("train_type", "*")}
        if dist == "exponential":
            d["probability"] = _number(f"{w} probability", item.get("probability", 1.0), 0.0, 1.0)
            d["mean_s"] = _number(f"{w} mean_s", item.get("mean_s"), 0.0, 86400.0)
        if dist == "empirical":
            if not isinstance(item.get("file"), str) or not item["file"]:
                raise JobError(f"{w} file: an empirical distribution needs the Parquet file of observed delays")
            d["file"] = item["file"]
        out.append(d)
    return tuple(out)


def rules(job) -> list[Rule]:
    """The primary-delay rules of a job, empirical files read (each refused with a one-line error)."""
    out = []
    for d in job.robustness.delays:
        if d["distribution"] != "empirical":
            out.append(Rule(d["kind"], d["distribution"], d["train_type"], d.get("probability", 1.0),
                            d.get("mean_s", 0.0)))
            continue
        out.append(Rule(d["kind"], "empirical", d["train_type"], values=tuple(_observed(job, d)), source=d["file"]))
    return out


def _observed(job, d: dict) -> np.ndarray:
    from planner.io.parquet import read_file

    path = job.resolve(d["file"])
    try:
        t = read_file(path)
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: cannot read the observed delays ({e}); give a Parquet file with a delay_s "
                         "column") from None
    if "delay_s" not in t.column_names:
        raise InputError(f"{path}: no delay_s column (observed delay in seconds); columns: {', '.join(t.column_names)}")
    v = np.asarray(t.column("delay_s").to_numpy(zero_copy_only=False), dtype=float)
    keep = np.ones(len(v), dtype=bool)
    for col, want in (("kind", d["kind"]), ("train_type", d["train_type"])):
        if col in t.column_names and want != "*":
            keep &= np.asarray(t.column(col).to_pylist(), dtype=object) == want
    v = v[keep]
    bad = np.flatnonzero(~np.isfinite(v) | (v < 0))
    if len(bad):
        raise InputError(f"{path} row {int(np.flatnonzero(keep)[bad[0]])} column delay_s: {v[bad[0]]!r} is not a "
                         "delay ≥ 0 s; observed early running counts as 0")
    if not len(v):
        raise InputError(f"{path}: no rows for kind {d['kind']!r} and train type {d['train_type']!r}")
    return v


def dwell_rule(job):
    """The minimum dwell of a station and train type: the job's exceptions, else ``min_dwell_s``."""
    r = job.robustness
    exc = list(r.min_dwell)

    def dwell(station: str, train_type: str) -> float:
        v = r.min_dwell_s
        for x in exc:
            if x["station_id"] in ("*", station) and x["train_type"] in ("*", train_type):
                v = x["min_dwell_s"]
        return v
    return dwell


def connections(job) -> list[tuple[str, str, str, float]]:
    """The job's turnarounds and connections (``[robustness] connections``), or none."""
    f = job.robustness.connections
    if not f:
        return []
    from planner.io.parquet import read_file

    path = job.resolve(f)
    try:
        t = read_file(path).to_pylist()
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: cannot read the connections ({e})") from None
    need = ("from_train", "to_train", "station_id", "min_s")
    out = []
    for i, row in enumerate(t):
        for c in need:
            if row.get(c) is None:
                raise InputError(f"{path} row {i} column {c}: missing; a connection needs {', '.join(need)}")
        out.append((str(row["from_train"]), str(row["to_train"]), str(row["station_id"]), float(row["min_s"])))
    return out


def key_of(job) -> list:
    """What of the job the day as it runs depends on, for the conflict unit's key (files by their digest)."""
    r = asdict(job.robustness)
    files = [d["file"] for d in job.robustness.delays if d.get("file")] + ([r["connections"]] if r["connections"] else [])
    digests = {}
    for f in files:
        p = Path(job.resolve(f))
        digests[f] = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "missing"
    return [r, digests]


def day_as_it_runs(check, line, job, *, days: int | None = None, seed: int | None = None, n_jobs: int = 1,
                   progress=None, stream: tuple[int, ...] = ()):
    """The predicted day, the statistics of ``days`` simulated days (None when 0), the page's summary and the
    day's holds (:func:`planner.delay.predicted.holds`, each marked knock-on or not); ``stream``: a section's
    own draws (:func:`planner.network.sections.stream_of`)."""
    from planner.delay.montecarlo import simulate
    from planner.delay.predicted import predict_day

    days = job.robustness.days if days is None else int(days)
    seed = job.robustness.seed if seed is None else int(seed)
    rs = rules(job)
    day = predict_day(check, min_dwell_s=dwell_rule(job), connections=connections(job))
    stats = simulate(day.net, rs, days, seed, n_jobs=n_jobs, progress=progress, stream=stream) if days > 0 else None
    # the day's conflicts are its holds; knock-on: those the timetable as planned does not have (pair and place)
    from planner.delay.predicted import LATE_S, holds

    planned = {(r["train_a"], r["train_b"], r["resource_id"]) for r in check.conflicts} | {
        (r["train_b"], r["train_a"], r["resource_id"]) for r in check.conflicts}
    held = holds(day, planned)
    knock = [h for h in held if h["knock_on"]]
    summary = {"days": days, "seed": seed, "rules": [r.text() for r in rs] or ["none"],
               "trains": len(day.net.train_ids), "events": day.net.n_events, "activities": day.net.n_activities,
               "dropped": day.net.dropped, "day_conflicts": len({(h["train_a"], h["train_b"]) for h in held}),
               "knock_on_conflicts": len({(h["train_a"], h["train_b"]) for h in knock}),
               "knock_on_places": sorted({h["place"] for h in knock}),
               "min_dwell_s": job.robustness.min_dwell_s, "late_trains": int(len(set(
                   np.asarray(day.net.train_ids)[day.net.ev_train[day.delay_s > LATE_S]]))) if day.net.n_events else 0,
               "max_delay_s": float(day.delay_s.max()) if day.net.n_events else 0.0}
    if stats is not None:
        from planner.delay.network import ARRIVAL

        arr = day.net.ev_kind == ARRIVAL
        for m in (60, 180, 300):  # share of all arrivals × days within m seconds
            summary[f"within_{m}s"] = float(stats.within(float(m))[arr].mean()) if arr.any() else 1.0
    return day, stats, summary, held


def merged_summary(parts: list[tuple[dict, int]]) -> dict:
    """The summary of a line's day as it runs from its sections' (:mod:`planner.network.sections`), each with the
    count of arrivals its shares are over: counts added, places joined, the largest delay the largest, each share
    of arrivals within a margin weighted by the section's arrivals. A line of one section: its summary."""
    if len(parts) == 1:
        return parts[0][0]
    first = parts[0][0]
    out = dict(first)
    for k in ("trains", "events", "activities", "dropped", "day_conflicts", "knock_on_conflicts", "late_trains"):
        out[k] = sum(p[k] for p, _ in parts)
    out["knock_on_places"] = sorted(set().union(*(p["knock_on_places"] for p, _ in parts)))
    out["max_delay_s"] = max(p["max_delay_s"] for p, _ in parts)
    total = sum(n for _, n in parts)
    for k in (k for k in first if k.startswith("within_")):
        out[k] = float(sum(p[k] * n for p, n in parts) / total) if total else 1.0
    return out
