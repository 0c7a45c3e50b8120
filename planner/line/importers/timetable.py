"""Timetables from outside: clock times as planners write them, and railML 2.x ``<timetable>``.

**Clock times.** Wherever a user writes a timetable (the CSV import's
``timetable.csv``, the ``[[timetable]]`` rows of an importer's ``--extra``
TOML) ``arrival_s`` and ``departure_s`` take seconds after midnight or a clock
time ``HH:MM`` / ``HH:MM:SS`` (fractions of a second allowed), with hours past
24 for after midnight of the operating day (``25:10:00`` = 90,600 s), as
:func:`clock_seconds` reads them.

**railML 2.x timetables.** :func:`railml_timetable` reads
``<timetable>/<trainParts>/<trainPart>`` with its ``<ocpsTT>/<ocpTT ocpRef
sequence ocpType>`` and their ``<times arrival departure arrivalDay
departureDay scope>``:

- only the OCPs that are stations of the imported line count; the others
  (junctions, stations of another line) are left out with a note;
- ``ocpType`` ``pass`` is a pass (the passing time is both arrival and
  departure), ``begin``, ``stop`` and ``end`` are stops; without ``ocpType``, a
  call is a stop when its arrival differs from its departure or it has a
  ``<stopDescription>``;
- times: the ``scheduled`` scope, else ``published``, else the first
  ``<times>``; ``arrivalDay``/``departureDay`` add days; a time earlier than the
  call before it is taken as after midnight (+24 h, with a note);
- the direction is the order of the train's stations along the line
  (``down`` when the first lies at lower chainage);
- the train type is the rolling stock named like the train part's category
  (``categoryRef`` → ``<category code>`` or its id), or the only train type
  when the import has one; rename a rolling stock to a category with
  ``[rolling_stock.NAME] train_type = "CAT"`` in the ``--extra`` TOML;
- the train id is the train part's ``trainNumber`` (its ``code``, else its
  id) where that is unique, else the part's id.
"""
from __future__ import annotations

import datetime as _dt
import math
import re

import pandas as pd

from planner.errors import SourceError
from planner.line.schema import TABLES

CLOCK_COLUMNS = ("arrival_s", "departure_s")
"""Timetable columns that accept a clock time as well as seconds after midnight."""

_CLOCK = re.compile(r"^\s*(\d{1,3}):([0-5]\d)(?::([0-5]\d(?:\.\d+)?))?\s*$")


def clock_seconds(value, where: str) -> float | None:
    """Seconds after midnight from a number, ``HH:MM[:SS[.s]]`` (hours may pass 24) or a TOML time.

    None and empty text give None (no time). Anything else is a one-line SourceError naming ``where``.

    >>> clock_seconds("05:02:25", "x"), clock_seconds("25:10", "x"), clock_seconds(600, "x")
    (18145.0, 90600.0, 600.0)
    """
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if isinstance(value, bool):
        raise SourceError(f"{where}: {value!r} is not a time; write HH:MM:SS or seconds after midnight")
    if isinstance(value, _dt.time):
        return value.hour * 3600.0 + value.minute * 60.0 + value.second + value.microsecond / 1e6
    if isinstance(value, (int, float)):
        x = float(value)
    else:
        text = str(value)
        m = _CLOCK.match(text)
        if m:
            x = int(m.group(1)) * 3600.0 + int(m.group(2)) * 60.0 + float(m.group(3) or 0.0)
        else:
            try:
                x = float(text)
            except ValueError:
                raise SourceError(f"{where}: {text!r} is not a time; write HH:MM:SS (e.g. 05:02:25, or 25:10:00 "
                                  f"for 01:10 after midnight) or seconds after midnight") from None
    if not math.isfinite(x) or x < 0:
        raise SourceError(f"{where}: {value!r} must be a time of day ≥ 0 (HH:MM:SS or seconds after midnight)")
    return x


# --------------------------------------------------------------------------- railML 2.x <timetable>
def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _kids(el, name: str) -> list:
    return [c for c in el if _local(c.tag) == name] if el is not None else []


def _times(doc_name: str, call) -> tuple[float | None, float | None]:
    """(arrival, departure) of an ``<ocpTT>`` [s after midnight of day 0]."""
    times = _kids(call, "times")
    if not times:
        return None, None
    by_scope = {t.get("scope"): t for t in times}
    t = next((by_scope[k] for k in ("scheduled", "published") if k in by_scope), times[0])
    out = []
    for attr in ("arrival", "departure"):
        where = f"{doc_name}: <ocpTT ocpRef={call.get('ocpRef')!r}> <times @{attr}>"
        x = clock_seconds(t.get(attr), where)
        day = t.get(f"{attr}Day")
        if x is not None and day not in (None, ""):
            try:
                x += 86400.0 * int(day)
            except ValueError:
                raise SourceError(f"{where}Day: {day!r} is not a whole number of days") from None
        out.append(x)
    return out[0], out[1]


def railml_timetable(root, doc_name: str, stations: dict[str, tuple[str, float]], train_types: list[str],
                     notes: list[str]) -> pd.DataFrame | None:
    """timetable rows from the railML ``<timetable>`` of ``root``, or None when the file has none.

    Parameters
    ----------
    stations : dict
        OCP id → (station_id, chainage [m]) for the stations of the imported line.
    train_types : list of str
        The import's train types (rolling stock names after the TOML's renames).
    """
    tts = [c for c in root if _local(c.tag) == "timetable"]
    parts = [p for tt in tts for ps in _kids(tt, "trainParts") for p in _kids(ps, "trainPart")]
    if not parts:
        return None
    cats = {}
    for tt in tts:
        for cs in _kids(tt, "categories"):
            for c in _kids(cs, "category"):
                cats[c.get("id")] = c.get("code") or c.get("name") or c.get("id")
    numbers = [p.get("trainNumber") or p.get("code") for p in parts]
    rows: list[dict] = []
    skipped_ocps: set[str] = set()
    short, rolled = [], 0
    for part, number in zip(parts, numbers):
        pid = part.get("id") or f"trainPart[{len(rows)}]"
        tid = number if number and numbers.count(number) == 1 else pid
        ttype = _train_type(doc_name, part, pid, cats, train_types)
        calls = []
        for ocps in _kids(part, "ocpsTT"):
            for k, call in enumerate(_kids(ocps, "ocpTT")):
                seq = call.get("sequence")
                calls.append((float(seq) if seq not in (None, "") else float(k), call))
        calls.sort(key=lambda c: c[0])
        kept, last = [], None
        for _, call in calls:
            ref = call.get("ocpRef")
            arr, dep = _times(doc_name, call)
            for_order = [x for x in (arr, dep) if x is not None]
            if last is not None:
                while for_order and min(for_order) < last:  # after midnight without a day attribute
                    arr = None if arr is None else arr + 86400.0
                    dep = None if dep is None else dep + 86400.0
                    for_order = [x for x in (arr, dep) if x is not None]
                    rolled += 1
            if for_order:
                last = max(for_order)
            if ref not in stations:
                skipped_ocps.add(str(ref))
                continue
            kind = call.get("ocpType")
            if kind == "pass":
                stops = False
            elif kind in ("begin", "stop", "end"):
                stops = True
            else:
                stops = bool(_kids(call, "stopDescription")) or (arr is not None and dep is not None and dep > arr)
            kept.append([ref, arr, dep, stops])
        if len(kept) < 2:
            short.append(tid)
            continue
        kept[0][1], kept[-1][2] = None, None  # the run begins and ends at the line's stations
        kept[0][3] = kept[-1][3] = True
        for c in kept:
            if not c[3]:  # a pass: its one time for both
                t = c[1] if c[1] is not None else c[2]
                c[1] = c[2] = t
        direction = "down" if stations[kept[-1][0]][1] > stations[kept[0][0]][1] else "up"
        for seq, (ref, arr, dep, stops) in enumerate(kept):
            rows.append(dict(train_id=str(tid), train_type=ttype, direction=direction, seq=seq,
                             station_id=stations[ref][0], arrival_s=arr, departure_s=dep, stops=stops))
    notes.append(f"timetable: {len({r['train_id'] for r in rows})} trains from {len(parts)} railML train parts")
    if skipped_ocps:
        notes.append(f"timetable: calls at {len(skipped_ocps)} OCPs that are not stations of the line left out "
                     f"({', '.join(sorted(skipped_ocps)[:5])}{' …' if len(skipped_ocps) > 5 else ''})")
    if short:
        notes.append(f"timetable: {len(short)} train parts with fewer than two calls on the line left out "
                     f"({', '.join(short[:5])}{' …' if len(short) > 5 else ''})")
    if rolled:
        notes.append(f"timetable: {rolled} times earlier than the call before them taken as after midnight (+24 h)")
    return pd.DataFrame(rows, columns=[f.name for f in TABLES["timetable"].schema])


def _train_type(doc_name: str, part, pid: str, cats: dict, train_types: list[str]) -> str:
    ref = part.get("categoryRef")
    cat = cats.get(ref, ref)
    for want in (cat, ref):
        if want in train_types:
            return want
    if len(train_types) == 1:
        return train_types[0]
    raise SourceError(f"{doc_name}: <trainPart id={pid!r}> @categoryRef: category {cat!r} is not a train type "
                      f"({', '.join(train_types)}); name a rolling stock after it with [rolling_stock.NAME] "
                      f"train_type = {cat!r} in the --extra TOML")


def railml_or_toml_timetable(root, doc_name: str, found: dict[str, dict], train_types: list[str], s) -> pd.DataFrame:
    """The railML import's timetable: the TOML's ``[[timetable]]`` rows when it has any, else the file's
    ``<timetable>``, else empty (listed as a default). ``found``: OCP id → the station row found on the line."""
    from planner.line.importers.common import timetable_table

    if s.extra is not None and s.extra.timetable:
        if any(_local(c.tag) == "timetable" for c in root):
            s.notes.append("timetable: the --extra TOML's [[timetable]] rows replace the file's <timetable>")
        return timetable_table(s)
    over = s.extra.stations if s.extra is not None else {}
    st = {k: (str(over.get(k, {}).get("station_id", k)), float(v["position_m"])) for k, v in found.items()}
    tt = railml_timetable(root, doc_name, st, train_types, s.notes)
    return timetable_table(s) if tt is None else tt
