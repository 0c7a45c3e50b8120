"""What every importer shares: the ``--extra`` TOML, documented defaults, the summary, the atomic write.

A source format describes infrastructure; it does not know where the front
of a stopping train should be, what an ATS-P beacon sends, the timetable, or
the ride-comfort limits. Those come from a small TOML file beside the source
(``--extra``), or from :data:`DEFAULTS`. Every default actually used is
recorded in the :class:`ImportSummary` with the elements it was used for, so
nothing is silently invented.

The ``--extra`` TOML is :data:`EXTRA_EXAMPLE` (every section optional).
"""
from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
import tempfile
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pandas as pd
import pyarrow as pa

from planner.errors import SourceError, SourceProblems, Violation
from planner.line.schema import RUNNING_SIDES, SCHEMA_VERSION, TABLES, TRACK_DIRECTIONS, write_line_table
from planner.line.importers.timetable import CLOCK_COLUMNS, clock_seconds

EXTRA_EXAMPLE = """
[line]
line_id = "coast"            # default: the source's line/path name
name = "Coast Line"          # default: the line id
max_speed_kmh = 120.0        # default: none (each train's own maximum where no speed limit applies)
approach_m = 800.0           # stopping-pattern start before the marker without a TASC beacon; default:
                             #  where the train must start braking + 10 %
running_side = "right"       # right or left: the side trains run on where both mains are signalled alike
                             #  both ways; default: the data's own (where a down and an up track run side by side)

[defaults]                   # replace any documented default, e.g.
platform_length_m = 180.0

[stations.OP_ID]             # by the source's id of the station / operational point
station_id = "CST"           # default: the source id
name = "Coast"
platform_length_m = 210.0
stop_down_m = 1300.0         # chainage of the stop marker (train front), direction down
stop_up_m = 1100.0

[stations.HILL]              # a station the source does not have (no OCP / operational point there):
position_m = 2500.0          #  give its chainage (railML: the absPos km post when every track has one)

[track_directions]           # where the source does not say it (signals alike both ways, no mainDir):
tr_4 = "up"                  #  the direction trains normally run a source track (down, up or both)

[categories]                 # train type = the source's train category (railML speed trainCategory,
EMU10 = "passenger"          #  railjson speed_limit_by_tag); as --category EMU10=passenger

[rolling_stock.NAME]         # by the source's name; any rolling_stock column, e.g.
train_type = "EMU10"         # default: the source's name (ids become file and partition names)
jerk_limit_kmh_s2 = 2.5
full_load_mass_t = 90.0

[[beacons]]                  # ATS-P ground beacons; `at` = a source element id (signal, detector,
beacon_id = "B1"             #  balise, operational point) or give position_m
at = "S12"
direction = "down"
kind = "signal"
telegram = "S12:G"
evaluation_point = true

[[timetable]]                # rows of timetable.parquet (a railML file's own <timetable> is read when
train_id = "101"             #  the TOML has none)
train_type = "EMU"
direction = "down"
seq = 0
station_id = "CST"
departure_s = "06:00:00"     # HH:MM[:SS], past 24:00 for after midnight ("25:10:00"), or s after midnight
stops = true
"""
"""An ``--extra`` TOML with every section (also shown in docs/line-database.md)."""

DEFAULTS: dict[str, tuple[object, str]] = {
    "platform_length_m": (200.0, "platform length where the source gives none [m]"),
    "stop_markers": ("platform ends", "stop markers at the platform end in each direction "
                                      "(down: centre + length/2, up: centre − length/2), clipped to the line"),
    "speed_limit_kind": ("civil", "kind of every imported speed restriction"),
    "has_beacon": (False, "no ATS-P beacon sends an imported restriction's pattern"),
    "line_max_speed": ("none", "no line max_speed_kmh: where no speed limit applies, each train runs at its own "
                               "maximum (OSRD's meaning of a missing speed section)"),
    "line_name": ("line id", "display name = the line id"),
    "line_id": ("source and path", "line id = railML: the <line> id; railjson: the file stem and the first and "
                                   "last point of --path (two paths of one file never share an id)"),
    "beacons": ("none", "no ATS-P beacons (add [[beacons]] to the TOML)"),
    "timetable": ("empty", "no trains (add [[timetable]] rows to the TOML)"),
    "missing_gradient": (0.0, "gradient of a railML track with no gradientChange [‰] (level)"),
    "beacon_kind": ("other", "kind of a beacon (railML balise, or [[beacons]] without kind)"),
    "beacon_telegram": ("", "telegram of a beacon the TOML gives none for (empty)"),
    "evaluation_point": (False, "a beacon is not an evaluation point unless the TOML says so"),
    "full_load_mass_t": (0.0, "passenger mass at 100 % load [t]"),
    "max_accel_kmh_s": ("comfort_acceleration", "acceleration cap when powering = the source's comfort "
                                                "acceleration (OSRD: the traction comfort limit)"),
    "brake_comfort_kmh_s": (3.3, "ride-comfort limit on stop braking [km/h/s] (0.92 m/s²); the source has none "
                                 "(its comfort acceleration limits powering, not braking)"),
    "service_brake_kmh_s": ("braking", "restriction braking = the source's braking deceleration"),
    "stop_brake_kmh_s": ("braking", "the train's own stopping brake = the source's braking deceleration"),
    "atsp_pattern_kmh_s": ("braking", "ATS-P pattern deceleration = the source's braking deceleration"),
    "jerk_limit_kmh_s2": (1.8, "ride-comfort jerk limit [km/h/s²] (0.5 m/s³)"),
    "speed_margin_kmh": (0.0, "on-board speed margin below the limit [km/h]"),
    "cruise": ("constant", "cruise mode"),
    "coast_band_kmh": (0.0, "sawtooth band [km/h] (unused with constant cruise)"),
}
"""Every default an importer may use: key → (value, what it means). ``[defaults]`` in the TOML overrides."""

OVERRIDABLE = frozenset(DEFAULTS) - {"stop_markers", "line_max_speed", "line_name", "line_id", "beacons", "timetable"}
"""Defaults with one value that ``[defaults]`` may replace (the others describe a rule or an absence)."""

_ROLLING_STOCK_COLS = frozenset(f.name for f in TABLES["rolling_stock"].schema)  # train_type renames
_SECTIONS = {"line", "defaults", "stations", "rolling_stock", "beacons", "timetable", "categories", "track_directions"}
_LINE_KEYS = {"line_id", "name", "max_speed_kmh", "approach_m", "running_side"}
_STATION_KEYS = {"station_id", "name", "platform_length_m", "stop_down_m", "stop_up_m", "position_m"}
_BEACON_KEYS = {f.name for f in TABLES["beacons"].schema} | {"at"}
_TIMETABLE_KEYS = {f.name for f in TABLES["timetable"].schema}


@dataclass
class ImportSummary:
    """What an import did: the source, the result, and every default it used."""

    source: str
    out: Path | None = None
    line_id: str = ""
    rows: dict[str, int] = field(default_factory=dict)
    defaults: dict[str, list[str]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    unused: list[str] = field(default_factory=list)
    """What the source gives that the line database does not take (named, never dropped silently)."""
    extra: "Extras | None" = None
    describe: Callable[[Violation], str] = str
    """How a violation of the written tables is named in terms of the source (CSV: file and line)."""
    warnings: list[str] = field(default_factory=list)
    """The written line's validation warnings, grouped by rule (:func:`planner.line.validate.format_warnings`):
    findings legitimate on some railways (a train longer than its platforms), said at import as ``validate`` says them."""

    def default(self, key: str, where: str | None = None):
        """The value of default ``key`` (the TOML's ``[defaults]`` first), recorded as used for ``where``."""
        value = self.extra.defaults.get(key) if self.extra is not None else None
        src = "TOML [defaults]" if value is not None else "default"
        if value is None:
            value = DEFAULTS[key][0]
        label = f"{key} = {value!r} ({src}: {DEFAULTS[key][1]})"
        self.defaults.setdefault(label, [])
        if where is not None and where not in self.defaults[label]:
            self.defaults[label].append(where)
        return value

    def lines(self) -> list[str]:
        """Printable summary: one fact per line, then every default used and where."""
        out = [f"imported {self.source} -> {self.out} (line_id {self.line_id}): valid"]
        out += [f"  {name + ':':<15}{n} row{'' if n == 1 else 's'}" for name, n in self.rows.items()]
        out.append(f"  defaults used: {len(self.defaults) or 'none'}")
        for label, where in self.defaults.items():
            tail = f" for {', '.join(where[:8])}{' …' if len(where) > 8 else ''}" if where else ""
            out.append(f"    - {label}{tail}")
        out += [f"  note: {n}" for n in self.notes]
        out += [f"  not used: {n}" for n in self.unused]
        if self.warnings:
            out.append("  warnings (they do not refuse the line; `planner validate` lists them too):")
            out += [f"    {w}" for w in self.warnings]
        return out


# --------------------------------------------------------------------------- the --extra TOML
@dataclass
class Extras:
    """The parsed ``--extra`` TOML (empty when none is given)."""

    path: str = "--extra"
    line: dict = field(default_factory=dict)
    defaults: dict = field(default_factory=dict)
    stations: dict = field(default_factory=dict)
    rolling_stock: dict = field(default_factory=dict)
    beacons: list = field(default_factory=list)
    timetable: list = field(default_factory=list)
    categories: dict = field(default_factory=dict)
    track_directions: dict = field(default_factory=dict)

    def err(self, where: str, message: str) -> SourceError:
        return SourceError(f"{self.path}: {where}: {message}")


def _check_keys(ex: Extras, where: str, table: dict, allowed: set[str]) -> None:
    if not isinstance(table, dict):
        raise ex.err(where, f"must be a table, found {type(table).__name__}")
    for k in table:
        if k not in allowed:
            raise ex.err(f"{where}.{k}", f"unknown key; expected one of {', '.join(sorted(allowed))}")


def load_extras(path: str | Path | None) -> Extras:
    """Read and check the ``--extra`` TOML; None gives an empty :class:`Extras`."""
    if path is None:
        return Extras()
    p = Path(path)
    ex = Extras(path=p.name)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SourceError(f"{p}: --extra file does not exist") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SourceError(f"{p.name}: not valid TOML ({e})") from None
    _check_keys(ex, "top level", data, _SECTIONS)
    ex.line = data.get("line", {})
    _check_keys(ex, "[line]", ex.line, _LINE_KEYS)
    ex.defaults = data.get("defaults", {})
    _check_keys(ex, "[defaults]", ex.defaults, set(OVERRIDABLE))
    ex.stations = data.get("stations", {})
    for k, v in ex.stations.items():
        _check_keys(ex, f"[stations.{k}]", v, _STATION_KEYS)
    ex.categories = data.get("categories", {})
    if not isinstance(ex.categories, dict) or not all(isinstance(v, str) for v in ex.categories.values()):
        raise ex.err("[categories]", 'map train types to the source\'s category names, e.g. EMU = "passenger"')
    ex.track_directions = data.get("track_directions", {})
    if not isinstance(ex.track_directions, dict) or not all(
            v in TRACK_DIRECTIONS for v in ex.track_directions.values()):
        raise ex.err("[track_directions]", "give each source track id the direction trains normally run it: "
                                           f"{', '.join(map(repr, TRACK_DIRECTIONS))}, e.g. tr_4 = \"up\"")
    ex.rolling_stock = data.get("rolling_stock", {})
    for k, v in ex.rolling_stock.items():
        _check_keys(ex, f"[rolling_stock.{k}]", v, set(_ROLLING_STOCK_COLS))
    for name, keys in (("beacons", _BEACON_KEYS), ("timetable", _TIMETABLE_KEYS)):
        rows = data.get(name, [])
        if not isinstance(rows, list):
            raise ex.err(name, "must be an array of tables ([[" + name + "]])")
        for i, r in enumerate(rows):
            _check_keys(ex, f"[[{name}]] #{i + 1}", r, keys)
        setattr(ex, name, rows)
    return ex


def number(value, where: str, fix: str = "", *, positive: bool = False) -> float:
    """A finite float from a source value, or a SourceError naming ``where``."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise SourceError(f"{where}: {value!r} is not a number{'; ' + fix if fix else ''}") from None
    if not math.isfinite(x) or (positive and not x > 0):
        need = "a number > 0" if positive else "a finite number"
        raise SourceError(f"{where}: {value!r} must be {need}{'; ' + fix if fix else ''}")
    return x


def braking_note(row: dict, source: str = "") -> str:
    """One summary line: what a train type's acceleration and braking limits are, and what a stop may ask.

    ``row`` is a rolling_stock row (railway units); ``source`` says where its values came from.
    """
    acc, comfort, brake = (float(row[c]) for c in ("max_accel_kmh_s", "brake_comfort_kmh_s", "stop_brake_kmh_s"))
    return (f"train type {row['train_type']}: acceleration cap {acc:.3g} km/h/s (max_accel_kmh_s), braking "
            f"comfort {comfort:.3g} km/h/s (brake_comfort_kmh_s), own stopping brake {brake:.3g} km/h/s "
            f"(stop_brake_kmh_s){' from ' + source if source else ''}; a stopping pattern asks for at most "
            f"{min(comfort, brake):.3g} km/h/s and the adhesion level")


# --------------------------------------------------------------------------- shared table builders
def line_table(line_id: str, start_m: float, end_m: float, s: ImportSummary) -> pd.DataFrame:
    """line.parquet from the TOML's [line] and the defaults."""
    ex = s.extra or Extras()
    lid = str(line_id)
    name = ex.line.get("name")
    if name is None:
        s.default("line_name")
        name = lid
    vmax = ex.line.get("max_speed_kmh")
    if vmax is None:
        s.default("line_max_speed")
    else:
        vmax = number(vmax, f"{ex.path}: [line] max_speed_kmh", positive=True)
    s.line_id = lid
    row = dict(line_id=lid, name=str(name), start_m=float(start_m), end_m=float(end_m), max_speed_kmh=vmax,
               schema_version=SCHEMA_VERSION)
    if ex.line.get("approach_m") is not None:
        row["approach_m"] = number(ex.line["approach_m"], f"{ex.path}: [line] approach_m", positive=True)
    if ex.line.get("running_side") is not None:
        if ex.line["running_side"] not in RUNNING_SIDES:
            raise SourceError(f"{ex.path}: [line] running_side = {ex.line['running_side']!r}; write "
                              f"{' or '.join(map(repr, RUNNING_SIDES))}: the side trains normally run on")
        row["running_side"] = ex.line["running_side"]
    return pd.DataFrame([row])


def station_table(found: list[dict], start_m: float, end_m: float, s: ImportSummary,
                  train_length_m: float = 0.0) -> pd.DataFrame:
    """stations.parquet from located stations ``{source_id, name, position_m[, platform_length_m,
    stop_down_m, stop_up_m]}``, the TOML's [stations.*] and the defaults.

    A default stop marker is the platform's far end in the running direction (the station's position ± half
    the platform), moved in, with a note, where a train of ``train_length_m`` (the longest imported type)
    standing there would have its tail beyond the line's end behind it: at a terminus the station's point
    is the line's end, and the validation refused a 400 m train's departure ("its tail is at −200.0 m")."""
    from planner.line.model import did_you_mean

    ex = s.extra or Extras()
    known = {st["source_id"] for st in found}
    found = list(found)
    for k, v in ex.stations.items():
        if k in known:
            continue
        if "position_m" not in v:
            listed = ", ".join(sorted(known)) or "none (the source has no stations on the path)"
            raise ex.err(f"[stations.{k}]", f"no station {k!r} on the imported path{did_you_mean(k, known)}; "
                                            f"stations are {listed}; to add a station the source does not "
                                            f"have, give its position_m")
        pos = number(v["position_m"], f"{ex.path}: [stations.{k}].position_m", "chainage in metres")
        if not start_m <= pos <= end_m:
            raise ex.err(f"[stations.{k}].position_m", f"{pos!r} is off the imported line [{start_m!r}, "
                                                       f"{end_m!r}] m")
        found.append(dict(source_id=k, name=k, position_m=pos))
        s.notes.append(f"station {k} added at {pos:g} m from [stations.{k}] position_m (not in the source)")
    rows = []
    for st in sorted(found, key=lambda r: r["position_m"]):
        sid = st["source_id"]
        over = {**{k: v for k, v in st.items() if v is not None}, **ex.stations.get(sid, {})}
        plat = over.get("platform_length_m")
        if plat is None:
            plat = s.default("platform_length_m", sid)
        plat = number(plat, f"station {sid}: platform_length_m", positive=True)
        pos = number(over["position_m"], f"station {sid}: position_m")
        down, up = over.get("stop_down_m"), over.get("stop_up_m")
        if down is None or up is None:
            s.default("stop_markers", sid)
        if down is None:
            down = _marker(sid, "down", min(pos + plat / 2, end_m), start_m + train_length_m, end_m, train_length_m,
                           s)
        else:
            down = number(down, f"station {sid}: stop_down_m")
        if up is None:
            up = _marker(sid, "up", max(pos - plat / 2, start_m), end_m - train_length_m, start_m, train_length_m, s)
        else:
            up = number(up, f"station {sid}: stop_up_m")
        rows.append(dict(station_id=str(over.get("station_id", sid)), name=str(over.get("name", sid)),
                         position_m=pos, stop_down_m=down, stop_up_m=up, platform_length_m=plat))
    return pd.DataFrame(rows, columns=[f.name for f in TABLES["stations"].schema])


def _marker(sid: str, direction: str, want: float, room: float, end: float, length: float, s: ImportSummary) -> float:
    """A default stop marker ``want``, moved to ``room`` (the nearest place where a train ``length`` long standing
    at it has its tail on the line) when it lies short of that, never past the line's far ``end``; with a note."""
    down = direction == "down"
    if (want >= room) if down else (want <= room):
        return want
    at = min(room, end) if down else max(room, end)
    s.notes.append(f"station {sid}: stop marker {direction} at {at:g} m, not {want:g} m, so that a {length:g} m train "
                   f"(the longest type) stands on the line (a terminus: the line ends {abs(want - at) + 0.0:g} m "
                   f"too close behind the default); give stop_{direction}_m in [stations.{sid}] to place it yourself")
    return at


def beacon_table(located: dict[str, float], s: ImportSummary, native: list[dict] | None = None) -> pd.DataFrame:
    """beacons.parquet: ``native`` rows from the source, then the TOML's [[beacons]] (``at`` = an element id)."""
    ex = s.extra or Extras()
    rows = list(native or [])
    by_id = {r["beacon_id"]: r for r in rows}
    for i, b in enumerate(ex.beacons):
        where = f"[[beacons]] #{i + 1}"
        b = dict(b)
        if b.get("beacon_id") in by_id:  # completes a beacon of the source (a railML balise)
            by_id[b["beacon_id"]].update(b)
            continue
        if "at" in b:
            at = b.pop("at")
            if at not in located:
                raise ex.err(f"{where}.at", f"no element {at!r} on the imported path; give an id of a signal, "
                                            f"detector, balise or station on it, or position_m")
            b.setdefault("position_m", located[at])
        for k in ("beacon_id", "position_m", "direction"):
            if k not in b:
                raise ex.err(where, f"missing key {k!r}" + (" (or at)" if k == "position_m" else ""))
        b["position_m"] = number(b["position_m"], f"{ex.path}: {where}.position_m")
        rows.append(b)
    if not rows:
        s.default("beacons")
    for r in rows:
        for col, key in (("kind", "beacon_kind"), ("telegram", "beacon_telegram"),
                         ("evaluation_point", "evaluation_point")):
            if r.get(col) is None:
                r[col] = s.default(key, str(r["beacon_id"]))
    return pd.DataFrame(rows, columns=[f.name for f in TABLES["beacons"].schema])


def timetable_table(s: ImportSummary) -> pd.DataFrame:
    """timetable.parquet from the TOML's [[timetable]] rows (empty by default)."""
    ex = s.extra or Extras()
    cols = [f.name for f in TABLES["timetable"].schema]
    if not ex.timetable:
        s.default("timetable")
    rows = []
    for i, r in enumerate(ex.timetable):
        for k in ("train_id", "train_type", "direction", "seq", "station_id", "stops"):
            if k not in r:
                raise ex.err(f"[[timetable]] #{i + 1}", f"missing key {k!r}")
        row = {c: r.get(c) for c in cols}
        for c in CLOCK_COLUMNS:
            row[c] = clock_seconds(row[c], f"{ex.path}: [[timetable]] #{i + 1}.{c}")
        rows.append(row)
    return pd.DataFrame(rows, columns=cols)


class Problems:
    """Every problem of one source file: element-level refusals are collected, then raised together.

    ``with problems.each(): ...`` around the reading of one element keeps the
    run going after a :class:`SourceError`; :meth:`check` raises them all at a
    phase boundary (one problem: its own line; several: :class:`SourceProblems`).
    """

    def __init__(self, source: str):
        self.source, self.items = source, []

    @contextlib.contextmanager
    def each(self):
        try:
            yield
        except SourceProblems as e:
            self.items += e.problems
        except SourceError as e:
            self.items.append(str(e))

    def check(self) -> None:
        if len(self.items) == 1:
            raise SourceError(self.items[0])
        if self.items:
            raise SourceProblems(self.source, self.items)


def category_map(s: ImportSummary, given: list[str] | None) -> dict[str, str]:
    """Train type → the source's train category: the TOML's ``[categories]``, then ``--category TYPE=CAT``."""
    out = dict((s.extra or Extras()).categories)
    for g in given or []:
        typ, sep, cat = str(g).partition("=")
        if not sep or not typ.strip() or not cat.strip():
            raise SourceError(f"--category: {g!r} must be TYPE=CATEGORY (a train type and the source's train "
                              f"category / speed tag, e.g. EMU=passenger)")
        out[typ.strip()] = cat.strip()
    return out


def check_categories(mapping: dict[str, str], rolling_stock: pd.DataFrame, offered: set[str], what: str,
                     s: ImportSummary) -> None:
    """Refuse a mapping that names an unknown train type or category; name the categories no type takes."""
    from planner.line.model import did_you_mean

    types = [str(t) for t in rolling_stock["train_type"]]
    for typ, cat in mapping.items():
        if typ not in types:
            raise SourceError(f"--category / [categories]: no train type {typ!r}{did_you_mean(typ, types)} "
                              f"(train types: {', '.join(types)})")
        if cat not in offered:
            raise SourceError(f"--category / [categories]: {typ}={cat}: the source has no {what} {cat!r}"
                              f"{did_you_mean(cat, offered)} (offered: {', '.join(sorted(offered)) or 'none'})")
    left = sorted(offered - set(mapping.values()))
    if left:
        s.unused.append(f"speed limits of {what} {', '.join(left)} (no train type maps to them; "
                        f"--category TYPE=CATEGORY)")


def path_id(text: str) -> str:
    """``text`` made a valid line id (file and partition name): other characters become ``_``, 64 at most."""
    t = re.sub(r"[^A-Za-z0-9._-]+", "_", str(text)).strip("._-") or "line"
    return t[:64]


# --------------------------------------------------------------------------- writing
def to_arrow(name: str, df: pd.DataFrame) -> pa.Table:
    """A DataFrame of table ``name`` as a pyarrow table with the declared schema (optional columns may be absent)."""
    spec = TABLES[name]
    fields = [f for f in spec.schema if f.name in df.columns or f.name not in spec.optional_columns]
    arrays = []
    for f in fields:
        if f.name not in df.columns:
            raise SourceError(f"{name}: column {f.name} is missing")
        values = [None if (isinstance(v, float) and math.isnan(v)) else v for v in df[f.name].tolist()]
        if pa.types.is_floating(f.type):
            values = [None if v is None else float(v) for v in values]
        arrays.append(pa.array(values, type=f.type))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=spec.schema.metadata))


def write_line(tables: dict[str, pd.DataFrame | pa.Table], out: str | Path, summary: ImportSummary,
               *, force: bool = False) -> ImportSummary:
    """Write the tables as a line database at ``out``: temp folder, validation, then one rename.

    Raises
    ------
    SourceError
        ``out`` exists (without ``force``), or the imported tables break a rule of
        docs/line-database.md; nothing is left behind.
    """
    from planner.line.loader import check_line

    edges = tables.get("edges")
    side = edges.attrs.get("running_side") if isinstance(edges, pd.DataFrame) else None
    if side is not None and isinstance(tables["line"], pd.DataFrame):  # the network's (the data's, or given)
        tables["line"]["running_side"] = side
    out = Path(out)
    if out.exists() and not force:
        raise SourceError(f"{out}: already exists; choose another --out or pass --force to replace it")
    made = [p for p in reversed(out.parents) if not p.exists()]  # removed again if the import fails
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.import-", dir=out.parent))
    done = False
    try:
        for name, t in tables.items():
            table = t if isinstance(t, pa.Table) else to_arrow(name, t)
            write_line_table(name, table, tmp / TABLES[name].file)
            summary.rows[name] = table.num_rows
        problems = check_line(tmp)
        if len(problems) == 1:
            raise SourceError(f"{summary.source}: the imported line would be invalid: {summary.describe(problems[0])}; "
                              f"fix the source or the --extra TOML (rules: docs/line-database.md)")
        if problems:
            raise SourceProblems(f"{summary.source}: the imported line would be invalid (rules: "
                                 f"docs/line-database.md)", [summary.describe(p) for p in problems])
        os.chmod(tmp, 0o755)
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
            os.replace(out, old / "x")
            os.replace(tmp, out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out)
        done = True
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
        if not done:
            for p in reversed(made):
                try:
                    p.rmdir()
                except OSError:
                    break
    summary.out = out
    from planner.line.loader import load_line
    from planner.line.validate import format_warnings

    found: list = []
    load_line(out, found)  # valid: checked above; the warnings are what the night's validate step would say
    summary.warnings = format_warnings(found)
    return summary


def load_json(path: str | Path) -> tuple[str, object]:
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SourceError(f"{p}: file does not exist") from None
    except UnicodeDecodeError as e:
        raise SourceError(f"{p.name}: not UTF-8 text ({e.reason})") from None
    try:
        return p.name, json.loads(text)
    except json.JSONDecodeError as e:
        raise SourceError(f"{p.name} line {e.lineno} column {e.colno}: not valid JSON ({e.msg})") from None
