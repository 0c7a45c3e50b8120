"""Public infrastructure and train types through the whole night: the issue-47 matrix, one command.

For each case of ``CASES`` (a railjson path or a railML line of a public file, stations by position where the
source has none) the file is imported as it is, with every train type of the matrix: OSRD's six test rolling
stocks (``rolling_stocks/*.json``) and TrainRuns.jl's regional DMU, intercity and 920 t freight, whose
published figures ``tests/public_trains.py`` types in and this script writes as OSRD rolling-stock JSON. Per
train type one train runs down and one up, departing together from the two ends, calling at every station
with 30 s dwell and running each leg at 108 % of its minimum running time; the next type's pair leaves when
the one before has arrived (+ 600 s), so each pair is one train each way on an empty line. The night runs,
and the table says per case what the product makes of an infrastructure nobody on the team wrote: the
flags, and which trains and tracks any conflict is between.

The public files are not in the repository. ``DATA`` holds ``infras/<name>.json`` (OSRD
``tests/data/infras/<name>/infra.json``), ``rolling_stocks/*.json`` (OSRD ``tests/data/rolling_stocks``) and
``railml/<file>``. Not part of ``make bench``. Run::

    .venv/bin/python benchmarks/public_matrix.py DATA --out WORK [--only small_infra]

It prints the markdown table of docs/importing.md ("Both directions on one night").
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

DWELL_S = 30.0
GAP_S = 600.0
RATIO = 1.08
START_S = 5 * 3600.0
MAX_ACCEL_MS2 = 5.0
"""TrainRuns.jl gives no acceleration cap (traction and adhesion limit it): the line database's upper bound."""
FLAGS = ("impossible", "short_bad_day", "infeasible_stops", "conflicts", "unrouted", "stalls", "unreachable")


@dataclass(frozen=True)
class Case:
    name: str
    kind: str  # railjson | railml
    file: str  # under DATA
    path: str  # railjson --path (operational points or track ids) / railML --line id
    stations: tuple = ()  # (id, position_m) where the source has no stations
    source: str = ""
    extra: str = ""  # more --extra TOML: what the source does not say (e.g. [track_directions])


_NS = "infras/nested_switches.json"
CASES = (
    Case("small_infra", "railjson", "infras/small_infra.json",
         "West_station,Mid_West_station,Mid_East_station,South_East_station", source="OSRD test infra"),
    Case("small_infra", "railjson", "infras/small_infra.json",
         "West_station,Mid_West_station,Mid_East_station,North_East_station", source="OSRD test infra"),
    Case("tiny_infra", "railjson", "infras/tiny_infra.json", "op.station_foo,op.station_bar", source="OSRD test infra"),
    Case("tiny_infra", "railjson", "infras/tiny_infra.json", "ne.micro.foo_a,ne.micro.bar_a",
         (("FOO", 100.0), ("MID", 5200.0), ("BAR", 10300.0)), source="OSRD test infra"),
    Case("overlapping_routes", "railjson", "infras/overlapping_routes.json", "op.a1,op.b1", source="OSRD test infra"),
    Case("overlapping_routes", "railjson", "infras/overlapping_routes.json", "op.a2,op.b2", source="OSRD test infra"),
    Case("nested_switches", "railjson", _NS, "T1,T2", (("A", 200.0), ("B", 6000.0), ("C", 11300.0)),
         source="OSRD test infra"),
    Case("nested_switches", "railjson", _NS, "T1,T4bis", (("A", 200.0), ("B", 4000.0), ("C", 10300.0)),
         source="OSRD test infra"),
    Case("one_line", "railjson", "infras/one_line.json", "track.0,track.9", (("A", 200.0), ("B", 5000.0), ("C", 9800.0)),
         source="OSRD test infra"),
    Case("one_line", "railjson", "infras/one_line.json", "track.2,track.7", (("A", 200.0), ("B", 3000.0), ("C", 5800.0)),
         source="OSRD test infra"),
    Case("example_script", "railjson", "infras/example_script.json", "track.1,track.3",
         (("A", 200.0), ("B", 1500.0), ("C", 2800.0)), source="OSRD test infra"),
    Case("example_script", "railjson", "infras/example_script.json", "track.0,track.6",
         (("A", 200.0), ("B", 2000.0), ("C", 3800.0)), source="OSRD test infra"),
    Case("Track-007_28-47", "railml", "railml/Track-007_28-47.railml.xml", "line_007_28_47",
         (("KM29", 29000.0), ("KM38", 38000.0), ("KM46", 46000.0)), source="railML 2.2, Finnish Transport Agency "
                                                                          "(infra2railml)"),
    Case("RailCOMPLETE ICT 2018", "railml", "railml/railcomplete_ict2018.railml", "line_0",
         (("S1", 462250.0), ("S2", 463250.0)), source="railML 2.2, RailCOMPLETE (CAD) export",
         # both mains are signalled alike both ways and the file has no mainDir: which is which is only in their
         # names (INBOUND, OUTBOUND); the through route tr_5 taken as the down main (km posts increasing)
         extra='[track_directions]\ntr_4 = "up"\ntr_5 = "down"\n'),
)


def _trainruns_stock(tt) -> tuple[dict, dict]:
    """One of tests/public_trains.py's train types as OSRD rolling-stock JSON (SI units), and the
    [rolling_stock.NAME] overrides OSRD's format has no field for (the load)."""
    curve = {"speeds": [float(v) for v in tt.traction_speed_ms], "max_efforts": [float(f) for f in tt.traction_effort_N]}
    return ({"name": tt.train_type, "length": tt.length_m, "mass": tt.empty_mass_kg, "max_speed": tt.max_speed_ms,
             "inertia_coefficient": 1.0 + tt.rotating_mass_factor, "comfort_acceleration": min(tt.max_accel_ms2, MAX_ACCEL_MS2),
             "gamma": {"type": "CONST", "value": tt.stop_brake_ms2},
             "rolling_resistance": {"type": "davis", "A": tt.davis_a_N, "B": tt.davis_b_N_per_ms,
                                    "C": tt.davis_c_N_per_ms2},
             "effort_curves": {"default_mode": "thermal",
                               "modes": {"thermal": {"curves": [], "default_curve": curve, "is_electric": False}}}},
            {"full_load_mass_t": tt.full_load_mass_kg / 1000.0} if tt.full_load_mass_kg else {})


def stocks(data: Path, work: Path, drop: tuple = ()) -> tuple[list[Path], str]:
    """The matrix's rolling-stock files and the TOML overrides that go with them (without the types ``drop``)."""
    from public_trains import tr_dmu, tr_freight, tr_ic

    files = [f for f in sorted((data / "rolling_stocks").glob("*.json")) if json.loads(f.read_text())["name"] not in drop]
    (work / "stock").mkdir(parents=True, exist_ok=True)
    toml = ""
    for tt in (t for t in (tr_dmu(), tr_ic(), tr_freight()) if t.train_type not in drop):
        rs, over = _trainruns_stock(tt)
        f = work / "stock" / f"{tt.train_type}.json"
        f.write_text(json.dumps(rs, indent=1))
        files.append(f)
        toml += f"\n[rolling_stock.{tt.train_type}]\n" + "".join(f"{k} = {v!r}\n" for k, v in over.items()) if over else ""
    return files, toml


def _cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "planner.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT)


def _import(case: Case, data: Path, files: list[Path], extra: Path, out: Path) -> subprocess.CompletedProcess:
    rs = [a for f in files for a in ("--rolling-stock", f)]
    where = ("--path", case.path) if case.kind == "railjson" else ("--line", case.path)
    return _cli("import", case.kind, data / case.file, *where, *rs, "--out", out, "--extra", extra, "--force")


def timetable(line) -> list[dict]:
    """Per train type a pair: one train down, one up, leaving the two ends together; pairs one after another."""
    from planner import running_time

    st = sorted(line.stations, key=lambda s: s.position_m)
    rows, t0, n = [], START_S, 0
    for tt in [t.train_type for t in line.train_types]:
        ends = []
        for direction, seq in (("down", st), ("up", st[::-1])):
            n += 1
            t = t0
            calls = [(seq[0].station_id, None, t)]
            for a, b in zip(seq[:-1], seq[1:]):
                t += round(RATIO * running_time(line, tt, a.station_id, b.station_id, ratio=1.0).time_s)
                calls.append((b.station_id, t, t + DWELL_S))
                t += DWELL_S
            calls[-1] = (calls[-1][0], calls[-1][1], None)
            ends.append(t)
            for k, (sid, arr, dep) in enumerate(calls):
                r = {"train_id": f"{'D' if direction == 'down' else 'U'}{n:02d}", "train_type": tt,
                     "direction": direction, "seq": k, "station_id": sid, "stops": True}
                r.update({} if arr is None else {"arrival_s": arr})
                r.update({} if dep is None else {"departure_s": dep})
                rows.append(r)
        t0 = max(ends) + GAP_S
    return rows


def _stations_toml(case: Case) -> str:
    return "".join(f"\n[stations.{sid}]\nposition_m = {pos!r}\n" for sid, pos in case.stations)


def _conflicts(out: Path) -> list[str]:
    import pandas as pd

    files = list((out / "outputs" / "latest" / "conflicts").rglob("*.parquet"))
    if not files:
        return []
    c = pd.concat([pd.read_parquet(f) for f in files])
    return sorted({f"{r.train_a}/{r.train_b} {r.rule} on {r.track}" for r in c.itertuples()})


def run_case(case: Case, data: Path, files: list[Path], stock_toml: str, work: Path) -> dict:
    from planner import load_line

    out = work / f"{case.name}-{case.path.replace(',', '-')}".replace(" ", "_")
    out.mkdir(parents=True, exist_ok=True)
    base = _stations_toml(case) + case.extra + stock_toml
    (out / "bare.toml").write_text(base)
    r = _import(case, data, files, out / "bare.toml", out / "bare")
    res = {"case": case, "import": r.returncode, "error": r.stderr.strip().splitlines()[-1:] if r.returncode else []}
    if r.returncode:
        return res
    line = load_line(out / "bare")
    rows = timetable(line)
    res.update(km=(line.end_m - line.start_m) / 1000.0, types=len(line.train_types), trains=len({r["train_id"] for r in rows}),
               notes=sum(ln.strip().startswith("note:") for ln in r.stdout.splitlines()))
    (out / "extra.toml").write_text(base + "".join(
        "\n[[timetable]]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in row.items()) for row in rows))
    r = _import(case, data, files, out / "extra.toml", out / "line")
    if r.returncode:
        res.update({"import": r.returncode, "error": r.stderr.strip().splitlines()[-1:]})
        return res
    (out / "job.toml").write_text(f'[job]\nlines = ["{out / "line"}"]\noutput_root = "{out / "outputs"}"\n'
                                  "[bundles]\nallow_development_key = true\n")
    r = _cli("run", out / "job.toml", "--no-progress")
    flags = next((ln.split("flags:", 1)[1] for ln in r.stdout.splitlines() if "flags:" in ln), "")
    res.update(night=r.returncode, stderr=r.stderr.strip()[-300:] if r.returncode else "",
               flags={k.strip(): int(v) for k, v in (p.rsplit(" ", 1) for p in flags.split(",") if p.strip())},
               conflicts=_conflicts(out))
    return res


def table(results: list[dict]) -> str:
    head = ("| infrastructure (source) | path / line | km | trains | import | night | impossible | short on a bad day "
            "| infeasible stops | conflicts | unrouted | conflicts between |\n|---|---|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in results:
        c = r["case"]
        path = c.path.replace(",", " → ") + ("" if not c.stations else " (stations " + ", ".join(
            f"{s} {p:g}" for s, p in c.stations) + " m)")
        if r["import"]:
            lines.append(f"| `{c.name}` ({c.source}) | {path} | | | refused: {' '.join(r['error'])[:160]} | | | | | | | |")
            continue
        f = r.get("flags", {})
        g = lambda k: str(f.get(k, "—"))  # noqa: E731
        lines.append(f"| `{c.name}` ({c.source}) | {path} | {r['km']:.1f} | {r['trains']} ({r['types']} types) | ok "
                     f"| {'published' if r.get('night') == 0 else 'exit ' + str(r.get('night'))} | {g('impossible')} "
                     f"| {g('short_bad_day')} | {g('infeasible_stops')} | {g('conflicts')} | {g('unrouted')} "
                     f"| {'; '.join(r.get('conflicts', [])[:4])} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("data", type=Path, help="folder with infras/, rolling_stocks/ and railml/ (public files)")
    ap.add_argument("--out", type=Path, required=True, help="work folder (created)")
    ap.add_argument("--only", default="", help="run only the cases whose name or path contains this")
    ap.add_argument("--drop", default="", help="train types left out, comma-separated (e.g. TR_FREIGHT: is any "
                                               "other train's verdict the freight's doing?)")
    a = ap.parse_args()
    work, data = a.out.resolve(), a.data.resolve()
    files, stock_toml = stocks(data, work, tuple(t for t in a.drop.split(",") if t))
    results = []
    for case in CASES:
        if a.only and a.only not in case.name and a.only not in case.path:
            continue
        res = run_case(case, data, files, stock_toml, work)
        print(f"# {case.name} {case.path}: import {res['import']}, night {res.get('night')}, "
              f"{res.get('flags') or res.get('error')} {res.get('stderr', '')}", file=sys.stderr, flush=True)
        results.append(res)
    print(table(results))


if __name__ == "__main__":
    main()
