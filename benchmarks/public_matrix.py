"""A public infrastructure through the whole night: import a railjson path, time trains, run, print the flags.

For each train type of the rolling stock files, one train each way along ``--path``, departing 600 s after the
one before, calling at every station of the path with 30 s dwell and running each leg at 108 % of its minimum
running time. The night's flags (conflicts, unrouted trains, stops that cannot be made, ...) say what the
product makes of an infrastructure nobody on the team wrote. Not part of ``make bench`` (the files are not in
the repository; OSRD publishes its test infrastructures and rolling stock under ``tests/data``).

Run::

    .venv/bin/python benchmarks/public_matrix.py small_infra/infra.json \\
        West_station,Mid_West_station,Mid_East_station,South_East_station fast_rolling_stock.json ... --out DIR
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

DWELL_S = 30.0
HEADWAY_S = 600.0
RATIO = 1.08


def _cli(*args, check: bool = True) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "planner.cli", *map(str, args)], capture_output=True, text=True)
    if check and r.returncode:
        raise SystemExit(f"planner {' '.join(map(str, args[:2]))} failed: {r.stderr.strip()[-800:]}")
    return r


def _import(infra: Path, path: list[str], stocks: list[Path], extra: Path, out: Path) -> None:
    rs = [a for s in stocks for a in ("--rolling-stock", s)]
    _cli("import", "railjson", infra, "--path", ",".join(path), *rs, "--out", out, "--extra", extra, "--force")


def _timetable(line) -> list[dict]:
    from planner import running_time

    st = sorted(line.stations, key=lambda s: s.position_m)
    rows, n = [], 0
    for tt in [t.train_type for t in line.train_types]:
        for direction, seq in (("down", st), ("up", st[::-1])):
            n += 1
            t = 6 * 3600.0 + HEADWAY_S * n
            calls = [(seq[0].station_id, None, t)]
            for a, b in zip(seq[:-1], seq[1:]):
                t += round(RATIO * running_time(line, tt, a.station_id, b.station_id, ratio=1.0).time_s)
                calls.append((b.station_id, t, t + DWELL_S))
                t += DWELL_S
            calls[-1] = (calls[-1][0], calls[-1][1], None)
            for k, (sid, arr, dep) in enumerate(calls):
                r = {"train_id": f"T{n}", "train_type": tt, "direction": direction, "seq": k, "station_id": sid,
                     "stops": True}
                r.update({} if arr is None else {"arrival_s": arr})
                r.update({} if dep is None else {"departure_s": dep})
                rows.append(r)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("infra", type=Path)
    ap.add_argument("path", help="operational points, comma-separated, in running order")
    ap.add_argument("stock", type=Path, nargs="+", help="OSRD rolling stock JSON files")
    ap.add_argument("--out", type=Path, required=True, help="work folder (created)")
    a = ap.parse_args()
    from planner import load_line

    out = a.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    path = a.path.split(",")
    (out / "bare.toml").write_text("")
    _import(a.infra, path, a.stock, out / "bare.toml", out / "bare")
    rows = _timetable(load_line(out / "bare"))
    (out / "extra.toml").write_text("".join(
        "\n[[timetable]]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in r.items()) for r in rows))
    _import(a.infra, path, a.stock, out / "extra.toml", out / "line")
    (out / "job.toml").write_text(f'[job]\nlines = ["{out / "line"}"]\noutput_root = "{out / "outputs"}"\n'
                                  "[bundles]\nallow_development_key = true\n")
    r = _cli("run", out / "job.toml", "--no-progress", check=False)
    flags = next((ln.strip() for ln in r.stdout.splitlines() if "flags:" in ln), r.stderr.strip()[-500:])
    print(f"{a.infra.stem} {' -> '.join(path)}: {len(rows)} calls, exit {r.returncode}; {flags}")


if __name__ == "__main__":
    main()
