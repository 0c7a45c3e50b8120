"""``docs/line-database.md``: the line-database contract, generated from :mod:`planner.line.schema`.

The column lists, types, nullability and meanings come from the declared
pyarrow schemas (one source); this module adds the prose a user needs around
them: conventions, the rules validation checks per table, and how to bring a
line from a spreadsheet, railjson or railML. ``planner schema`` prints it;
``tests/test_schema_doc.py`` checks that the committed file is the generated one.
"""
from __future__ import annotations

from planner.line.importers.common import DEFAULTS, EXTRA_EXAMPLE
from planner.line.schema import (
    BEACON_KINDS,
    CRUISE_MODES,
    LIMIT_DIRECTIONS,
    NODE_KINDS,
    TRACK_DIRECTIONS,
    SCHEMA_VERSION,
    RENAMED_COLUMNS,
    TABLES,
    column_range,
    describe,
)

_EXTRA_EXAMPLE = EXTRA_EXAMPLE.strip("\n").splitlines()
DOC_PATH = "docs/line-database.md"
"""Where the generated document lives in the repository (validation messages point here)."""

_RULES: dict[str, list[str]] = {
    "line": ["`line_id` names the line in every output (partition value `line=`, bundle names); the "
             "folder may have any name.", "`start_m` < `end_m`; `max_speed_kmh` null: no line maximum (each "
             "train's own applies where no restriction does); `approach_m` null or absent: the start from the "
             f"physics; `schema_version` = {SCHEMA_VERSION}."],
    "stations": ["`station_id` unique and not empty; rows sorted by strictly increasing `position_m`.",
                 "Platform centre and stop markers inside [`start_m`, `end_m`] of `line`."],
    "gradients": ["`start_m` < `end_m`; rows sorted by `start_m`, not overlapping; a gap is level track.",
                  "Every segment inside the line's range; at most one row per metre of line (also for "
                  "`curves` and `speed_limits`): a denser table is a sampled curve, not a table of segments."],
    "curves": ["As for gradients (sorted, non-overlapping, gaps are straight track)."],
    "speed_limits": [f"`direction` one of {', '.join(LIMIT_DIRECTIONS)}; "
                     "`train_type` null or a train type of `rolling_stock`.",
                     "Restrictions may overlap: the lowest applies. Where none applies, the lower of the "
                     "line's and the train's maximum speed does."],
    "beacons": ["`beacon_id` unique; `direction` down or up; "
                f"`kind` one of {', '.join(BEACON_KINDS)}; position inside the line's range."],
    "signals": ["Optional file. `signal_id` unique; `direction` down or up; position inside the line's range."],
    "rolling_stock": ["`train_type` unique.",
                      "`speed_margin_kmh` below the lowest speed the train type meets (the line's and its own "
                      "maximum, every restriction for it or for every train type): the on-board maximum is that "
                      "speed minus the margin.",
                      "Any positive `service_brake_kmh_s`, `stop_brake_kmh_s`, `atsp_pattern_kmh_s`, whatever the "
                      "gradients: on a climb that slows the train more than its braking curve asks it brakes less, "
                      "or powers; on a descent whose pull the brake cannot overcome, no stopping pattern stops it "
                      "there, a flag on that leg (`no_stop`), not an error.",
                      f"`cruise` one of {', '.join(CRUISE_MODES)}; `coast_band_kmh` > 0 for sawtooth.",
                      "Three limits kept apart: `max_accel_kmh_s` caps acceleration when powering (a source's "
                      "traction comfort limit goes here); `brake_comfort_kmh_s` is the ride-comfort limit on the "
                      "braking of a stop; `stop_brake_kmh_s` is the train's own stopping brake. A stopping pattern "
                      "asks the brake for at most min(braking comfort, adhesion level, stopping brake) and never "
                      "stops harder than the stopping brake.",
                      *[f"Schema 1 folders: `{old}` is now `{new}`, {why}. A folder with the old name is read "
                        "under the new one with a note, and `planner line upgrade DIR` rewrites it."
                        for (t, new), (old, why) in RENAMED_COLUMNS.items() if t == "rolling_stock"]],
    "traction": ["Per train type: `speed_kmh` starts at 0, strictly increasing, and reaches the train's "
                 "`max_speed_kmh`. Every train type of `rolling_stock` has a curve."],
    "timetable": ["Per train: one `train_type` and `direction`; `seq` runs 0..n-1; at least two calls; "
                  "null `arrival_s` only at seq 0 and null `departure_s` only at the last call.",
                  "Times never decrease along `seq`; consecutive stations follow the direction "
                  "(down: increasing chainage). May have no rows.",
                  "Where a train stands (its origin, its terminus, every call with `stops`) its front is at the "
                  "station's stop marker for its direction and its tail one train length (`rolling_stock."
                  "length_m`) behind; the tail must lie inside the line's range (down: ≥ `start_m`, up: ≤ "
                  "`end_m`), or the train would stand on track the database does not describe.",
                  "Warning only (printed by `planner validate`, not refused): a train longer than the platform "
                  "where it stands. Real railways do this with selective door opening (door cut: only the "
                  "doors along the platform open), and the planner's physics does not use platform lengths."],
    "nodes": ["Optional file (with `edges`). `node_id` unique; "
              f"`kind` one of {', '.join(NODE_KINDS)}; `station_id`, when given, names a station."],
    "edges": ["Optional file (with `nodes`). `edge_id` unique; both ends name nodes; `direction`, when given, "
              f"one of {', '.join(TRACK_DIRECTIONS)}.",
              "The route search keeps a train to the tracks of its own direction and takes a track used both "
              "ways only where no track of its direction leads on (single track, a crossover, a station's "
              "other platform). Where `direction` is null or the column absent, the track's name says it: "
              "a name beginning with `D` is a down track, `U` an up track, anything else both."],
}


def _rows(name: str) -> str:
    spec = TABLES[name]
    if spec.max_rows is not None and spec.max_rows == spec.min_rows:
        return f"exactly {spec.min_rows} row"
    if spec.min_rows:
        return f"at least {spec.min_rows} row{'s' if spec.min_rows > 1 else ''}"
    return "any number of rows"


def line_database_doc() -> str:
    """The Markdown text of ``docs/line-database.md``."""
    out = [
        f"# Line database, schema v{SCHEMA_VERSION}",
        "",
        "<!-- Generated by `planner schema` from planner/line/schema.py; do not edit by hand: "
        "run `planner schema --write docs/line-database.md`. -->",
        "",
        "A line database is a folder with one Parquet file per table below (`<table>.parquet`).",
        "The folder may have any name: the line is named by `line.parquet`'s `line_id`, and job",
        "files name line folders. These tables and columns are a public contract: you may add your",
        "own columns and tables (they are ignored on load), but not rename or drop these.",
        "",
        "Conventions:",
        "",
        "- units are in the column names: `_m` metres, `_kmh` km/h, `_kmh_s` km/h/s, `_kmh_s2` km/h/s²,",
        "  `_t` tonnes, `_kN` kilonewtons, `_permil` ‰, `_s` seconds;",
        "- chainage (`*_m` positions) grows away from the line's origin; direction `down` runs towards",
        "  increasing chainage, `up` towards decreasing;",
        "- gradients are positive when rising towards increasing chainage;",
        "- a missing value is null (never NaN); only columns marked nullable may hold one.",
        "",
        "`planner validate LINE` checks every rule below and names the file, the 0-based row (with",
        "the row's id), the column and what is wrong, e.g.",
        "`gradients.parquet row 7 (start_m=4200.0) column start_m: overlaps row 6, which ends at 4350.0`.",
        "Nothing is computed from a database that fails validation.",
        "",
        "Every number column has a range (column `range` of the tables below; `[a, b]` includes both",
        "ends, `(a, b]` not `a`), checked on every value that is not null: a unit slip, a lost decimal",
        "point or a 1e308 is refused up front, naming the cell, instead of failing late in a computation.",
        "The bounds are generous: they refuse what no railway has, never a heavy freight train, a",
        "high-speed line or a tight tramway curve. Why each bound is where it is: [Value ranges](#value-ranges).",
        "",
        "## Bringing your own line",
        "",
        "- `planner import csv --template DIR` writes one commented CSV per table with these columns;",
        "  fill them in a spreadsheet, then `planner import csv DIR --out lines/<name>`.",
        "- `planner import railjson INFRA.json --path OP1,OP2,... --rolling-stock RS.json --out ...` reads",
        "  OSRD railjson infrastructure and rolling stock.",
        "- `planner import railml FILE --line ID --rolling-stock RS.json --out ...` reads railML 2.x",
        "  infrastructure (the tracks of one `<line>` of `<trackGroups>`) and OSRD rolling stock.",
        "- `planner export csv LINE --out DIR` writes a line database as CSV (the reverse of import).",
        "",
        "The railjson and railML imports also write the track network (`nodes`, `edges`: switches,",
        "crossings, detectors, buffer stops and platforms, loops and second tracks placed on the line's",
        "chainage), and the railML import the file's `<timetable>`; docs/importing.md says how.",
        "Timetable times (`arrival_s`, `departure_s`) may be written as clock times `HH:MM:SS` in the",
        "CSV and the TOML, with hours past 24 after midnight.",
        "",
        "What a source cannot give (stop markers, beacon telegrams, timetable, comfort and jerk limits)",
        "comes from a small TOML file (`--extra`) or a documented default; every default used is listed",
        "in the import's summary. Imports write to a temporary folder, validate it, and only then",
        "rename it to `--out`.",
        "",
        "The `--extra` TOML (every section optional):",
        "",
        "```toml",
        *_EXTRA_EXAMPLE,
        "```",
        "",
        "Defaults an import may use (each one used is listed in the summary with the elements it",
        "was used for; `[defaults]` in the TOML replaces the value):",
        "",
        "| default | value | meaning |",
        "|---|---|---|",
        *[f"| `{k}` | `{v!r}` | {m} |" for k, (v, m) in DEFAULTS.items()],
        "",
        "## Tables",
        "",
    ]
    for name, spec in TABLES.items():
        need = "required" if spec.required else "optional"
        out += [f"### `{spec.file}` ({need}; {_rows(name)})", ""]
        out += ["| column | type | nullable | range | meaning |", "|---|---|---|---|---|"]
        for (col, typ, nullable, desc), field in zip(describe(name), spec.schema):
            opt = " (optional column)" if col in spec.optional_columns and "optional" not in desc else ""
            rng = column_range(field)
            out.append(f"| `{col}` | {typ} | {'yes' if nullable else 'no'} | {'' if rng is None else rng} | "
                       f"{desc.replace('|', chr(92) + '|')}{opt} |")
        out.append("")
        for r in _RULES.get(name, []):
            out.append(f"- {r}")
        out.append("")
    out += ["## Value ranges", "", "| range | columns | why |", "|---|---|---|"]
    for (rng, why), cols in _ranges().items():
        out.append(f"| {rng} | {', '.join(cols)} | {why} |")
    return "\n".join(out).rstrip() + "\n"


def _ranges() -> dict[tuple[str, str], list[str]]:
    """Each declared range with its reason, and the columns (``table.column``) that have it."""
    out: dict[tuple[str, str], list[str]] = {}
    for name, spec in TABLES.items():
        for field in spec.schema:
            rng = column_range(field)
            if rng is not None:
                out.setdefault((str(rng), rng.why), []).append(f"`{name}.{field.name}`")
    return out
