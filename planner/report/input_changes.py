"""The input changes of two runs (:func:`planner.report.changes.compare_runs`): code, job parameters and line-table
rows (:func:`input_changes`), and the operating days' own inputs, each temporary restriction that came into force,
was lifted or changed and each train that runs on one day only, from the two manifests (:func:`day_input_changes`).
Each change is added to a :class:`~planner.report.changes.LineChanges` and returned with its *reach*: what a leg
must share with it to be traced to it (a stretch of chainage, a direction, a train type, a train)."""
from __future__ import annotations

import json
from pathlib import Path

from planner.report.changes import LineChanges, _canon, _extent, _flatten, _num, _row_text, _str, _text, diff_table
from planner.report.published_run import line_inputs

RESTRICTION_FIELDS = ("start_m", "end_m", "limit_kmh", "direction", "track", "train_type", "valid_from",
                      "valid_until", "has_beacon", "whole_day")
"""What of a temporary restriction in force is compared between two runs' operating days."""


def input_changes(ch: LineChanges, old_dir: Path, old_m: dict, new_dir: Path, new_m: dict) -> dict[int, dict]:
    """Code, parameter and line-table rows; returns the line-table changes by id with their reach."""
    import pyarrow.parquet as pq

    if old_m.get("code_digest") != new_m.get("code_digest"):
        ov = (old_m.get("software") or {}).get("planner", "?")
        nv = (new_m.get("software") or {}).get("planner", "?")
        ch.add("code", "planner", f"planner code changed (version {ov} → {nv}, code digest "
               f"{str(old_m.get('code_digest'))[:12]} → {str(new_m.get('code_digest'))[:12]}): every result may move",
               field_="code_digest", before=old_m.get("code_digest"), after=new_m.get("code_digest"))
    po, pn = _flatten(old_m.get("parameters", {})), _flatten(new_m.get("parameters", {}))
    for k in sorted(set(po) | set(pn)):
        if k in ("job.keep_runs", "job.output_root"):
            continue
        if _canon(po.get(k)) != _canon(pn.get(k)):
            ch.add("parameter", k, f"job parameter {k}: {_text(po.get(k)) or '(unset)'} → {_text(pn.get(k)) or '(unset)'}",
                   field_=k.rsplit(".", 1)[-1], before=po.get(k), after=pn.get(k),
                   delta=_num(pn.get(k)) - _num(po.get(k)) if not isinstance(po.get(k), bool) else None)
    reach: dict[int, dict] = {}
    rec_o = next((x for x in old_m.get("lines", []) if x.get("line_id") == ch.line_id), None)
    rec_n = next((x for x in new_m.get("lines", []) if x.get("line_id") == ch.line_id), None)
    if rec_o is None:
        ch.notes.append(f"line {ch.line_id} is new in this run: nothing to compare it with")
        return reach
    if rec_n is None or rec_o.get("source_digest") == rec_n.get("source_digest"):
        return reach
    fo, fn = line_inputs(old_dir, old_m, ch.line_id), line_inputs(new_dir, new_m, ch.line_id)
    if fo is None or fn is None:
        ch.add("line_table", "line database", f"line database {ch.line_id} changed (source digest "
               f"{str(rec_o.get('source_digest'))[:12]} → {str(rec_n.get('source_digest'))[:12]}); "
               "the base run kept no copy of its tables, so the rows cannot be named",
               field_="source_digest", before=rec_o.get("source_digest"), after=rec_n.get("source_digest"))
        return reach
    names = sorted({p.stem for p in fo.glob("*.parquet")} | {p.stem for p in fn.glob("*.parquet")})
    for name in names:
        po_, pn_ = fo / f"{name}.parquet", fn / f"{name}.parquet"
        if po_.is_file() and pn_.is_file() and po_.read_bytes() == pn_.read_bytes():
            continue
        if not po_.is_file() or not pn_.is_file():
            ch.add("line_table", name, f"table {name}.parquet {'added' if pn_.is_file() else 'removed'}",
                   field_="table", before="" if pn_.is_file() else name, after=name if pn_.is_file() else "")
            continue
        old, new = pq.read_table(po_).to_pandas(), pq.read_table(pn_).to_pandas()
        for kind, o, n, cols in diff_table(name, old, new):
            row = n if n is not None else o
            what = _row_text(name, row)
            ext = _extent(name, row)
            if kind == "changed" and ext is not None and o is not None:
                eo = _extent(name, o)
                if eo:
                    ext = (min(ext[0], eo[0]), max(ext[1], eo[1]))
            scope = {"extent": ext, "train_type": row.get("train_type") if name in ("rolling_stock", "traction", "speed_limits") else None,
                     "train_id": row.get("train_id") if name == "timetable" else None,
                     "direction": row.get("direction") if name in ("speed_limits", "beacons", "signals") else None,
                     "all": name in ("line",)}
            lo, hi = (ext if ext else (None, None))
            if kind == "changed":
                for c in cols:
                    b, a = o.get(c), n.get(c)
                    d = _num(a) - _num(b) if not isinstance(a, (bool, str)) and a is not None and b is not None else None
                    cid = ch.add("line_table", name, f"{what}: {c} {_text(b)} → {_text(a)}", field_=c, before=b,
                                 after=a, delta=d, direction=scope["direction"], train_type=_str(scope["train_type"]),
                                 train_id=_str(scope["train_id"]), from_m=lo, to_m=hi)
                    reach[cid] = scope
            else:
                cid = ch.add("line_table", name, f"{what}: row {kind}", field_="row",
                             before=json.dumps(o, default=str, ensure_ascii=False, sort_keys=True) if o else "",
                             after=json.dumps(n, default=str, ensure_ascii=False, sort_keys=True) if n else "",
                             direction=scope["direction"], train_type=_str(scope["train_type"]),
                             train_id=_str(scope["train_id"]), from_m=lo, to_m=hi)
                reach[cid] = scope
    return reach


def day_input_changes(ch: LineChanges, old_m: dict, new_m: dict) -> dict[int, dict]:
    """The operating days' inputs: temporary restrictions in force on one day and not on the other (or in force
    on both, changed), and trains that run on one day only; returns them by id with their reach."""
    def of(m):
        return next((x for x in (m.get("operating_day") or {}).get("lines", []) if x.get("line_id") == ch.line_id),
                    None)

    o, n = of(old_m), of(new_m)
    if o is None or n is None:
        return {}
    days = f"{(old_m.get('operating_day') or {}).get('day')} → {(new_m.get('operating_day') or {}).get('day')}"
    reach: dict[int, dict] = {}
    ro = {r["restriction_id"]: r for r in o.get("restrictions", [])}
    rn = {r["restriction_id"]: r for r in n.get("restrictions", [])}
    for rid in sorted(set(ro) | set(rn)):
        a, b = ro.get(rid), rn.get(rid)
        r = b or a
        text = (f"{r['start_m']:.0f}–{r['end_m']:.0f} m, {r['limit_kmh']:g} km/h, {r['direction']}"
                + (f", track {r['track']}" if r.get("track") else "")
                + (f", {r['train_type']} only" if r.get("train_type") else ""))
        scope = {"extent": (float(r["start_m"]), float(r["end_m"])), "train_type": r.get("train_type"),
                 "direction": r.get("direction"), "train_id": None, "all": False}
        common = dict(direction=r.get("direction"), train_type=_str(r.get("train_type")),
                      from_m=float(r["start_m"]), to_m=float(r["end_m"]))
        if a is None or b is None:
            cid = ch.add("restriction", rid, f"restriction {rid} ({text}) {'came into force' if b else 'lifted'} "
                         f"(operating day {days})", field_="row", before="" if b else "in force",
                         after="in force" if b else "", **common)
            reach[cid] = scope
            continue
        moved = [f for f in RESTRICTION_FIELDS if _canon(a.get(f)) != _canon(b.get(f))]
        if moved:
            cid = ch.add("restriction", rid, f"restriction {rid} ({text}) changed: " + ", ".join(
                f"{f} {_text(a.get(f)) or '(none)'} → {_text(b.get(f)) or '(none)'}" for f in moved),
                field_=",".join(moved), before=json.dumps({f: a.get(f) for f in moved}, default=str),
                after=json.dumps({f: b.get(f) for f in moved}, default=str), **common)
            reach[cid] = scope
    off_o, off_n = set(o.get("trains_not_running", [])), set(n.get("trains_not_running", []))
    for tid, runs in sorted([(t, True) for t in off_o - off_n] + [(t, False) for t in off_n - off_o]):
        cid = ch.add("train", tid, f"train {tid} {'runs' if runs else 'does not run'} on {days.split(' → ')[1]} "
                     f"({'did not run' if runs else 'ran'} on {days.split(' → ')[0]})", field_="runs",
                     before=not runs, after=runs, train_id=tid)
        reach[cid] = {"extent": None, "train_type": None, "direction": None, "train_id": tid, "all": False}
    return reach
