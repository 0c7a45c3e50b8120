"""Build the sample line's daily feed ``feeds/sample/`` (the Minato Line's restrictions and calendar).

Run ``python feeds/sample/build.py [--out DIR]``; without ``--out`` the Parquet files
are written next to this script. Deterministic (no clock, no random numbers, explicit
schemas: the feed's declared tables of :mod:`planner.line.daily`), so a re-run
reproduces the committed files. README.md beside it explains the schedule.

The static line ``lines/sample/`` is not touched: its timetable holds every train
that may run; this feed says on which days each runs, and which temporary speed
restrictions are in force when.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))  # the project's planner, for the feed's declared schemas

from planner.line.daily import FEED_TABLES, restrictions_table  # noqa: E402

TIME_ZONE = "Asia/Tokyo"  # the job's [day] time_zone (jobs/nightly.toml)
TIMETABLE_YEAR = ("2026-04-01", "2027-03-31")  # the timetable in force: one fiscal year

# Services. The base service `daily` (the 1xxx locals and rapids, 264 trains) runs every day: on
# weekends and holidays it is the whole timetable. The weekday service `weekday` adds the 2xxx
# rush-hour extras (92 E10 trains) from Monday to Friday.
SERVICES = [
    # service_id, Mon..Sun
    ("daily", (True, True, True, True, True, True, True)),
    ("weekday", (True, True, True, True, True, False, False)),
]
# Dated exceptions (GTFS calendar_dates): 2 = removed, 1 = added.
EXCEPTIONS = [
    ("weekday", "2026-11-03", 2),  # Culture Day (Tuesday): holiday service
    ("weekday", "2026-11-23", 2),  # Labour Thanksgiving Day (Monday): holiday service
    ("weekday", "2026-12-05", 1),  # Saturday of the Minato port festival: the rush-hour extras run
    ("weekday", "2026-12-29", 2),  # year-end holidays: holiday service
    ("weekday", "2026-12-30", 2),
    ("weekday", "2026-12-31", 2),
    ("weekday", "2027-01-01", 2),  # New Year's Day (Friday)
]

# Temporary speed restrictions around the sample job's fixed day, Monday 2026-11-30 (local times,
# Asia/Tokyo). Chainages on the Minato Line: TKD 11 200, OHS 18 200 (the longest, busiest
# interstation), KWB 4 200, HGO 7 200, MDR 8 800, YMT 22 200, KTA 23 900.
RESTRICTIONS = [
    dict(restriction_id="TSR-2026-098", start_m=1500.0, end_m=1800.0, limit_kmh=40.0, direction="both",
         train_type=None, valid_from="2026-11-09T01:00", valid_until="2026-11-13T05:00",
         reason="sleeper replacement Minato-Sakuramachi, four nights", has_beacon=False),
    dict(restriction_id="TSR-2026-101", start_m=14200.0, end_m=14600.0, limit_kmh=45.0, direction="both",
         train_type=None, valid_from="2026-11-24T23:00", valid_until="2026-12-04T09:00",
         reason="rail renewal Takadai-Ohashi: ten nights of works, slow order until the track has settled",
         has_beacon=False),
    dict(restriction_id="TSR-2026-104", start_m=6000.0, end_m=6150.0, limit_kmh=25.0, direction="down",
         train_type=None, valid_from="2026-11-29T14:20", valid_until="2026-12-02T16:00",
         reason="rail defect (head check) on the down track Kawabata-Higashi-Oka, until the rail is changed",
         has_beacon=False),
    dict(restriction_id="TSR-2026-102", start_m=23100.0, end_m=23400.0, limit_kmh=60.0, direction="both",
         train_type=None, valid_from="2026-11-26T10:00", valid_until="2026-12-18T16:00",
         reason="formation works Yamate-Kitayama, temporary ATS-P beacon installed", has_beacon=True),
    dict(restriction_id="TSR-2026-107", start_m=9200.0, end_m=9500.0, limit_kmh=70.0, direction="both",
         train_type="E8", valid_from="2026-12-07T00:00", valid_until="2026-12-11T05:00",
         reason="Midori river bridge bearing inspection: E8 sets (heaviest axle load) only", has_beacon=False),
]


def train_services(timetable: Path) -> list[dict]:
    """Each timetable train's service: the 2xxx rush-hour extras are `weekday`, the rest `daily`."""
    ids = sorted(set(pq.read_table(timetable, columns=["train_id"]).column("train_id").to_pylist()))
    return [dict(train_id=t, service_id="weekday" if t.startswith("2") else "daily") for t in ids]


def tables() -> dict[str, pa.Table]:
    days = ("monday", "tuesday", "wednesday", "thursday", "friday", "saturday", "sunday")
    cal = [dict(service_id=s, **dict(zip(days, flags)), start_date=TIMETABLE_YEAR[0], end_date=TIMETABLE_YEAR[1])
           for s, flags in SERVICES]
    exc = [dict(service_id=s, date=d, exception_type=t) for s, d, t in EXCEPTIONS]
    rows = {"restrictions": RESTRICTIONS, "calendar": cal, "calendar_dates": exc,
            "train_services": train_services(HERE.parents[1] / "lines" / "sample" / "timetable.parquet")}
    return {name: restrictions_table(r) if name == "restrictions" else  # its optional column only when used
            pa.Table.from_pylist(r, schema=FEED_TABLES[name].schema) for name, r in rows.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for name, table in tables().items():
        path = args.out / FEED_TABLES[name].file
        tmp = path.with_name(f".{path.name}.tmp")
        pq.write_table(table, tmp)
        tmp.replace(path)
        print(f"wrote {path} ({table.num_rows} rows)")


if __name__ == "__main__":
    main()
