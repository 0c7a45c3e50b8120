"""A line's daily feed: loading, the validation rules (one line each: file, row, column, fix), imports
from CSV and OSRD JSON (validated, atomic), the [day] job keys, and the sample feed's days.

The tiny line (tests/linedb.py): 0 … 5000 m, line maximum 100 km/h, train types EMU10 and EMU6,
trains 101 (down) and 202 (up).
"""
from __future__ import annotations

import json
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from linedb import write_line_db
from planner.cli import app
from planner.errors import InputError, JobError, LineValidationError
from planner.job.config import load_job
from planner.job.day import day_inputs, day_record, resolve_day, with_day
from planner.line.daily import FEED_TABLES, load_feed
from planner.line.importers.restrictions import import_restrictions
from planner.line.loader import load_line

ROOT = Path(__file__).resolve().parents[1]
TZ = "Asia/Tokyo"
OK = dict(restriction_id="R1", start_m=1000.0, end_m=1400.0, limit_kmh=45.0, direction="both", train_type=None,
          valid_from="2026-11-30T01:00", valid_until="2026-12-02T05:00", reason="renewal", has_beacon=False)


def write_feed(folder: Path, **tables: list[dict]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name, rows in tables.items():
        pq.write_table(pa.Table.from_pylist(rows, schema=FEED_TABLES[name].schema), folder / f"{name}.parquet")
    return folder


def calendar_rows(weekend: bool = False) -> dict[str, list[dict]]:
    flags = dict(monday=True, tuesday=True, wednesday=True, thursday=True, friday=True, saturday=weekend,
                 sunday=weekend)
    return dict(calendar=[dict(service_id="wk", **flags, start_date="2026-11-01", end_date="2026-12-31")],
                calendar_dates=[dict(service_id="wk", date="2026-11-23", exception_type=2)],
                train_services=[dict(train_id="101", service_id="wk"), dict(train_id="202", service_id="wk")])


@pytest.fixture()
def tiny(tmp_path):
    return load_line(write_line_db(tmp_path / "tiny"))


def problems(feed: Path, line, tz: str = TZ) -> list[str]:
    with pytest.raises(LineValidationError) as e:
        load_feed(feed, line, tz)
    return [str(v) for v in e.value.violations]


def test_a_valid_feed_loads_in_si(tmp_path, tiny):
    feed = load_feed(write_feed(tmp_path / "f", restrictions=[OK], **calendar_rows()), tiny, TZ)
    (r,) = feed.restrictions
    assert r.limit_ms == pytest.approx(12.5) and r.valid_from == "2026-11-30T01:00"
    assert r.valid_from_s == 1795968000  # 2026-11-29T16:00Z, by hand: 01:00 JST is 16:00 UTC the day before
    assert r.valid_until_s - r.valid_from_s == (2 * 24 + 4) * 3600
    assert feed.calendar.train_service == {"101": "wk", "202": "wk"}


@pytest.mark.parametrize("edit, expected", [
    (dict(end_m=5200.0), "restrictions.parquet row 0 (restriction_id=R1) column end_m: stretch 1000.0–5200.0 m is "
                         "outside the line 0.0–5000.0 m"),
    (dict(start_m=1400.0, end_m=1000.0), "column end_m: end_m 1000.0 must be greater than start_m 1400.0"),
    (dict(valid_from="2026-12-03T00:00"), "column valid_until: 2026-12-02T05:00 is not after valid_from "
                                          "2026-12-03T00:00"),
    (dict(valid_from="2026-11-30T01:00+09:00"), "column valid_from: '2026-11-30T01:00+09:00' has a UTC offset"),
    (dict(valid_until="2026-12-02"), "column valid_until: '2026-12-02' has no time of day"),
    (dict(valid_until="02/12/2026 05:00"), "column valid_until: '02/12/2026 05:00' is not a date-time"),
    (dict(limit_kmh=100.0), "column limit_kmh: 100.0 km/h is not below the line maximum 100.0 km/h"),
    (dict(limit_kmh=0.0), "column limit_kmh: 0.0 km/h: a limit must be positive"),
    (dict(direction="north"), "column direction: 'north'; write one of both, down, up"),
    (dict(train_type="EMU99"), "column train_type: unknown train type 'EMU99'; the line has EMU10, EMU6"),
    (dict(restriction_id="a/b"), "column restriction_id: 'a/b' cannot name a restriction"),
])
def test_each_bad_restriction_is_one_line_naming_file_row_column(tmp_path, tiny, edit, expected):
    got = problems(write_feed(tmp_path / "f", restrictions=[{**OK, **edit}]), tiny)
    assert len(got) == 1 and expected in got[0], got
    assert "\n" not in got[0]


def test_duplicate_ids_and_every_problem_at_once(tmp_path, tiny):
    rows = [OK, {**OK, "end_m": 9000.0}, {**OK, "restriction_id": "R2", "limit_kmh": -5.0}]
    got = problems(write_feed(tmp_path / "f", restrictions=rows), tiny)
    assert [g.split(" column")[0] for g in got] == ["restrictions.parquet row 1 (restriction_id=R1)"] * 2 + [
        "restrictions.parquet row 2 (restriction_id=R2)"]
    assert "duplicate id (also row 0)" in got[0]


def test_a_local_time_the_clocks_skip_is_refused(tmp_path, tiny):
    # Berlin: 2026-03-29 02:00-03:00 does not exist
    got = problems(write_feed(tmp_path / "f", restrictions=[{**OK, "valid_from": "2026-03-29T02:30"}]), tiny,
                   "Europe/Berlin")
    assert got == ["restrictions.parquet row 0 (restriction_id=R1) column valid_from: '2026-03-29T02:30' does not "
                   "exist in Europe/Berlin (the clocks jump over it); write a time after the jump"]


def test_calendar_rules(tmp_path, tiny):
    t = calendar_rows()
    t["train_services"] = [dict(train_id="101", service_id="sunday_only"), dict(train_id="999", service_id="wk")]
    t["calendar_dates"].append(dict(service_id="wk", date="2026-11-31", exception_type=2))
    t["calendar_dates"].append(dict(service_id="wk", date="2026-12-01", exception_type=3))
    got = problems(write_feed(tmp_path / "f", **t), tiny)
    assert got == [
        "calendar_dates.parquet row 1 (service_id=wk date=2026-11-31) column date: '2026-11-31' is not a date; "
        "write YYYY-MM-DD",
        "calendar_dates.parquet row 2 (service_id=wk date=2026-12-01) column exception_type: 3; write 1 (service "
        "added on this date) or 2 (removed)",
        "train_services.parquet row 0 (train_id=101) column service_id: unknown service id 'sunday_only'; define "
        "it in calendar or calendar_dates (wk)",
        "train_services.parquet row 1 (train_id=999) column train_id: train '999' is not in the line's timetable; "
        "delete the row or add the train to timetable.parquet",
        "train_services.parquet column train_id: 1 timetable train(s) have no service, first 202; add a row for "
        "each",
    ]


def test_every_timetable_train_needs_a_service(tmp_path, tiny):
    t = calendar_rows()
    t["train_services"] = t["train_services"][:1]
    got = problems(write_feed(tmp_path / "f", **t), tiny)
    assert got == ["train_services.parquet column train_id: 1 timetable train(s) have no service, first 202; "
                   "add a row for each"]
    t = calendar_rows()
    t["calendar"][0]["end_date"] = "2026-10-01"
    del t["train_services"]
    got = problems(write_feed(tmp_path / "g", **t), tiny)
    assert got[0] == "calendar.parquet row 0 (service_id=wk) column end_date: 2026-10-01 is before start_date " \
                     "2026-11-01"
    assert got[1].startswith("train_services.parquet: missing: the feed has a calendar")


def job_file(tmp_path: Path, day: str = "", feeds: bool = True, extra: str = "") -> Path:
    write_line_db(tmp_path / "lines" / "tiny")
    (tmp_path / "jobs").mkdir(exist_ok=True)
    p = tmp_path / "jobs" / "j.toml"
    p.write_text(f'[job]\nlines = ["lines/tiny"]\n[day]\nday = "{day}"\ntime_zone = "{TZ}"\n'
                 + ('feeds = ["feeds/tiny"]\n' if feeds else "") + extra)
    return p


def test_a_day_without_service_is_a_note_and_the_day_goes_into_the_record(tmp_path):
    write_feed(tmp_path / "feeds" / "tiny", restrictions=[OK], **calendar_rows())
    job = load_job(job_file(tmp_path, "2026-11-29"))  # a Sunday: the weekday service does not run
    line = load_line(tmp_path / "lines" / "tiny")
    d = day_inputs(job, line)
    assert d.trains == () and d.cancelled == ("101", "202")
    assert any("no train runs on 2026-11-29 (Sunday)" in n for n in d.notes)
    assert [r.restriction_id for r in d.restrictions] == ["R1"]  # in force from 01:00 on the 30th, before 03:00
    notes: list[str] = []
    rec = day_record(with_day(job, "2026-11-23"), [line], notes)  # a Monday, removed by calendar_dates
    assert rec["day"] == "2026-11-23" and rec["lines"][0]["trains_not_running"] == ["101", "202"]
    assert rec["lines"][0]["restrictions"] == [] and len(notes) == 1
    d = day_inputs(with_day(job, "2026-12-02"), line)  # the restriction ends 05:00, after the day's 03:00 start
    assert d.trains == ("101", "202") and [r.restriction_id for r in d.restrictions] == ["R1"]
    assert day_inputs(with_day(job, "2026-12-03"), line).restrictions == ()


def test_day_job_keys(tmp_path):
    (tmp_path / "feeds" / "tiny").mkdir(parents=True)
    assert resolve_day(load_job(job_file(tmp_path, "2026-11-30"))).day.day == "2026-11-30"
    job = load_job(job_file(tmp_path))
    # 20:00 JST on 29 November = 11:00 UTC: the next operating day is the 30th
    assert resolve_day(job, now_s=1795950000).day.day == "2026-11-30"
    with pytest.raises(InputError, match="--day: expected a date YYYY-MM-DD, found '30.11.2026'"):
        with_day(job, "30.11.2026")
    bad = job_file(tmp_path, "2026-13-01", extra='start_hour = 24\n').read_text().replace(TZ, "Mars/Olympus")
    (tmp_path / "jobs" / "j.toml").write_text(bad)
    with pytest.raises(JobError) as e:
        load_job(tmp_path / "jobs" / "j.toml")
    msg = str(e.value)
    assert "[day] day: expected a date YYYY-MM-DD" in msg and "[day] start_hour: must be a whole hour 0..23" in msg
    assert "[day] time_zone: unknown time zone 'Mars/Olympus'" in msg


def test_feeds_need_one_folder_per_line_and_a_time_zone(tmp_path):
    p = job_file(tmp_path, "2026-11-30")
    p.write_text(p.read_text().replace('time_zone = "Asia/Tokyo"\n', "").replace(
        '["feeds/tiny"]', '["feeds/tiny", "feeds/two"]'))
    with pytest.raises(JobError) as e:
        load_job(p)
    msg = str(e.value)
    assert "[day] feeds: 2 feed(s) for 1 line(s) of [job] lines" in msg
    assert "[day] time_zone: a daily feed's times are local" in msg
    assert "daily feed folder 'feeds/tiny' does not exist" in msg


# --------------------------------------------------------------------------- imports
CSV = """# temporary speed restrictions
restriction_id,start_m,end_m,limit_kmh,direction,train_type,valid_from,valid_until,reason,has_beacon
C1,2000.0,2300.0,25.0,down,,2026-11-29T14:20,2026-12-02T16:00,rail defect,false
C2,3000.0,3400.0,60.0,both,EMU6,2026-11-26T10:00,2026-12-18T16:00,"formation works, beacon",true
"""


def test_csv_import_appends_refuses_duplicates_and_replaces(tmp_path, tiny):
    feed = write_feed(tmp_path / "f", restrictions=[OK])
    src = tmp_path / "r.csv"
    src.write_text(CSV)
    import_restrictions(src, tiny, feed, tz=TZ)
    got = load_feed(feed, tiny, TZ).restrictions
    assert [r.restriction_id for r in got] == ["R1", "C1", "C2"]
    assert got[2].train_type == "EMU6" and got[2].has_beacon and got[1].train_type is None
    before = (feed / "restrictions.parquet").read_bytes()
    with pytest.raises(LineValidationError) as e:
        import_restrictions(src, tiny, feed, tz=TZ)
    assert str(e.value.violations[0]).startswith("r.csv line 3 column restriction_id: 'C1' is already in")
    assert (feed / "restrictions.parquet").read_bytes() == before
    import_restrictions(src, tiny, feed, tz=TZ, replace=True)
    assert [r.restriction_id for r in load_feed(feed, tiny, TZ).restrictions] == ["C1", "C2"]


def test_a_bad_csv_row_changes_nothing_and_names_its_line(tmp_path, tiny):
    feed = write_feed(tmp_path / "f", restrictions=[OK])
    before = (feed / "restrictions.parquet").read_bytes()
    src = tmp_path / "r.csv"
    src.write_text(CSV.replace("2026-11-26T10:00", "2026-12-19T10:00").replace("2300.0", "5300.0"))
    with pytest.raises(LineValidationError) as e:
        import_restrictions(src, tiny, feed, tz=TZ)
    assert [str(v) for v in e.value.violations] == [
        "r.csv line 3 column end_m: stretch 2000.0–5300.0 m is outside the line 0.0–5000.0 m; give chainages of "
        "this line",
        "r.csv line 4 column valid_until: 2026-12-18T16:00 is not after valid_from 2026-12-19T10:00; a restriction "
        "must end after it starts"]
    assert (feed / "restrictions.parquet").read_bytes() == before
    r = CliRunner().invoke(app, ["restrictions", "import", str(src), "--line", str(tmp_path / "tiny"),
                                 "--feed", str(feed), "--time-zone", TZ])
    assert r.exit_code == 1 and r.output.count("\n") == 1 and "r.csv line 3 column end_m" in r.output


def test_osrd_temporary_speed_limits_import_onto_the_line(tmp_path):
    from importsrc import write_railjson
    from planner.line.importers.railjson import import_railjson

    i, rs, x = write_railjson(tmp_path / "src")
    import_railjson(i, ["W", "M", "E"], [rs], tmp_path / "coast", extra=x, line_id="coast")
    line = load_line(tmp_path / "coast")
    tsl = {"speed_limit_group_name": "night works", "speed_limits": [
        # T2 runs backwards on the path (offset x is chainage 5000 - x): offsets 1000-1400 are 3600-4000;
        # a range in the path's direction of T2 (STOP_TO_START) is down, the other up: both.
        {"obj_id": "tsl-1", "speed_limit": 40 / 3.6, "start_date_time": "2026-11-30T01:00:00",
         "end_date_time": "2026-12-01T05:00:00Z",
         "track_ranges": [{"track": "T2", "begin": 1000, "end": 1400, "direction": "STOP_TO_START"},
                          {"track": "T2", "begin": 1000, "end": 1400, "direction": "START_TO_STOP"}]},
        {"obj_id": "tsl-2", "speed_limit": 30 / 3.6, "start_date_time": "2026-11-30T01:00:00",
         "end_date_time": "2026-11-30T06:00:00",
         "track_ranges": [{"track": "T1", "begin": 100, "end": 300, "direction": "START_TO_STOP"}]},
    ]}
    src = tmp_path / "tsl.json"
    src.write_text(json.dumps(tsl))
    feed = tmp_path / "feed"
    s = import_restrictions(src, line, feed, tz=TZ, infra=i, path_ops=["W", "M", "E"])
    got = load_feed(feed, line, TZ).restrictions
    assert [(r.restriction_id, r.start_m, r.end_m, r.direction) for r in got] == [
        ("tsl-1", 3600.0, 4000.0, "both"), ("tsl-2", 100.0, 300.0, "down")]
    assert got[0].limit_ms == pytest.approx(40 / 3.6) and not got[0].has_beacon
    assert got[0].valid_until == "2026-12-01T14:00:00"  # 05:00 UTC is 14:00 in Tokyo
    assert any("has_beacon = False" in ln for ln in s.lines())
    with pytest.raises(InputError, match="--infra"):
        import_restrictions(src, line, feed, tz=TZ)


# --------------------------------------------------------------------------- the sample
def test_the_sample_feed_around_the_sample_day():
    job = load_job(ROOT / "jobs" / "nightly.toml")
    line = load_line(ROOT / "lines" / "sample")
    d = day_inputs(job, line)  # Monday 2026-11-30: weekday service, every train
    assert d.window.start_local == "2026-11-30T03:00:00+09:00" and d.window.length_s == 86400
    assert len(d.trains) == len(line.trains) == 356 and d.cancelled == ()
    assert [r.restriction_id for r in d.restrictions] == ["TSR-2026-101", "TSR-2026-104", "TSR-2026-102"]
    beacon = [r.restriction_id for r in d.restrictions if r.has_beacon]
    assert beacon == ["TSR-2026-102"]
    holiday = day_inputs(with_day(job, "2026-11-23"), line)  # Labour Thanksgiving Day: no rush-hour extras
    assert len(holiday.trains) == 264 and all(t.startswith("2") for t in holiday.cancelled)
    assert holiday.restrictions == ()
    renewal = next(r for r in d.restrictions if r.restriction_id == "TSR-2026-101")
    assert renewal.end_m - renewal.start_m == 400.0 and renewal.limit_ms * 3.6 == pytest.approx(45.0)
    nights = (renewal.valid_until_s - renewal.valid_from_s) / 86400
    assert 9 < nights < 10.5  # ten nights of works
    assert (ROOT / "lines" / "sample" / "daily").exists() is False  # the static line folder holds no feed


def test_the_sample_feed_is_its_build_scripts_output(tmp_path):
    import subprocess
    import sys

    subprocess.run([sys.executable, str(ROOT / "feeds" / "sample" / "build.py"), "--out", str(tmp_path)],
                   check=True, capture_output=True)
    for spec in FEED_TABLES.values():
        assert pq.read_table(tmp_path / spec.file).equals(pq.read_table(ROOT / "feeds" / "sample" / spec.file))


def test_the_docs_list_every_feed_column_as_declared():
    doc = (ROOT / "docs" / "operating-day.md").read_text()
    for spec in FEED_TABLES.values():
        assert f"#### `{spec.file}`" in doc
        for f in spec.schema:
            row = f"| `{f.name}` | {f.type} | {'yes' if f.nullable else 'no'} | {f.metadata[b'description'].decode()} |"
            assert row in doc, f"docs/operating-day.md: {spec.file} {f.name} differs from the declared schema"


def test_an_import_into_a_feed_with_a_broken_calendar_is_refused(tmp_path, tiny):
    t = calendar_rows()
    t["train_services"][0]["service_id"] = "nope"
    feed = write_feed(tmp_path / "f", restrictions=[{**OK, "limit_kmh": 120.0}], **t)
    src = tmp_path / "r.csv"
    src.write_text(CSV)
    for replace in (False, True):  # --replace drops the bad old restriction, not the calendar's problem
        with pytest.raises(LineValidationError) as e:
            import_restrictions(src, tiny, feed, tz=TZ, replace=replace)
        files = [v.file for v in e.value.violations]
        assert files == (["restrictions.parquet"] if not replace else []) + ["train_services.parquet"]


def test_restrictions_show_prints_the_day(tmp_path):
    write_feed(tmp_path / "feeds" / "tiny", restrictions=[OK], **calendar_rows())
    job = job_file(tmp_path, "2026-11-30")
    r = CliRunner().invoke(app, ["restrictions", "show", str(job), "--day", "2026-11-29"])
    assert r.exit_code == 0, r.output
    assert r.output.splitlines() == [
        "lines/tiny: operating day 2026-11-29 (Sunday) 2026-11-29T03:00:00+09:00 to 2026-11-30T03:00:00+09:00 (24 h)",
        "  trains: 0 run, 2 do not (101, 202)",
        "  restrictions in force: 1",
        "    R1: 1000–1400 m 45 km/h both, 2026-11-30T01:00 → 2026-12-02T05:00 (part of the day; DB-fed pattern): "
        "renewal",
        # R1 starts at 01:00 on the 30th, inside Sunday's operating day, not Saturday's; no train runs either day
        "  since Saturday 2026-11-28: R1 added; the same trains run",
        "  note: tiny: no train runs on 2026-11-29 (Sunday) by the calendar of feeds/tiny: is a service missing "
        "for that day?",
    ]


def test_an_osrd_limit_off_the_lines_path_reaches_its_track_and_a_piece_on_no_track_is_named(tmp_path):
    """The branch TB leaves the line's path at switch SW1 (T1's end, 3000 m) and runs on in chainage, so its
    offsets 100-500 are 3100-3500 m; its one signal faces trains running along it: its track is D:TB. A range
    on it was dropped (only the path's tracks were looked at); a range on a track of no network is named."""
    from importsrc import write_railjson
    from planner.line.importers.railjson import import_railjson

    i, rs, x = write_railjson(tmp_path / "src")
    import_railjson(i, ["W", "M", "E"], [rs], tmp_path / "coast", extra=x, line_id="coast")
    line = load_line(tmp_path / "coast")
    assert "D:TB" in {e.track for e in line.network.edges}
    tsl = {"speed_limits": [
        {"obj_id": "branch", "speed_limit": 20 / 3.6, "start_date_time": "2026-11-30T01:00:00",
         "end_date_time": "2026-11-30T06:00:00",
         "track_ranges": [{"track": "TB", "begin": 100, "end": 500, "direction": "START_TO_STOP"},
                          {"track": "NOWHERE", "begin": 0, "end": 50, "direction": "START_TO_STOP"}]},
    ]}
    src = tmp_path / "tsl.json"
    src.write_text(json.dumps(tsl))
    feed = tmp_path / "feed"
    s = import_restrictions(src, line, feed, tz=TZ, infra=i, path_ops=["W", "M", "E"])
    got = load_feed(feed, line, TZ).restrictions
    assert [(r.restriction_id, r.start_m, r.end_m, r.direction, r.track) for r in got] == [
        ("branch", 3100.0, 3500.0, "down", "D:TB")]
    assert any("track range NOWHERE 0–50 m lies on no track of the line's network" in n for n in s.notes)


def _sample_project(tmp_path):
    import shutil

    for name in ("lines", "feeds", "jobs"):
        shutil.copytree(ROOT / name, tmp_path / name)
    return tmp_path / "jobs" / "nightly.toml", tmp_path / "feeds" / "sample" / "restrictions.parquet"


def test_the_restriction_chores_read_the_line_feed_and_zone_from_the_job(tmp_path):
    """list, lift, remove, export and import --job: the job names the line, its feed and its time zone (the
    import repeated all three); each edit is validated and written atomically."""
    job, feed = _sample_project(tmp_path)
    run = lambda *a: CliRunner().invoke(app, ["restrictions", *map(str, a)])  # noqa: E731
    before = pq.read_table(feed)
    r = run("list", job)
    assert r.exit_code == 0 and r.output.count("\n  TSR-") == 5 and "local times, Asia/Tokyo" in r.output
    # export, then import it back in place of the feed's: the same table
    assert run("export", job, "--out", tmp_path / "r.csv").exit_code == 0
    assert run("import", tmp_path / "r.csv", "--job", job, "--replace").exit_code == 0
    assert pq.read_table(feed).equals(before)
    # lift one early: only its valid_until changes; outside its validity is refused and nothing is written
    r = run("lift", job, "TSR-2026-102", "--at", "2026-12-01T09:00")
    assert r.exit_code == 0, r.output
    rows = {x["restriction_id"]: x for x in pq.read_table(feed).to_pylist()}
    assert rows["TSR-2026-102"]["valid_until"] == "2026-12-01T09:00"
    lifted = feed.read_bytes()
    r = run("lift", job, "TSR-2026-102", "--at", "2026-12-05T09:00")
    assert r.exit_code == 1 and r.output.count("\n") == 1 and "lift it inside that time" in r.output
    assert feed.read_bytes() == lifted
    # remove one; an unknown id is one line naming the feed's ids
    assert run("remove", job, "TSR-2026-098").exit_code == 0
    assert "TSR-2026-098" not in {x["restriction_id"] for x in pq.read_table(feed).to_pylist()}
    r = run("remove", job, "NOPE")
    assert r.exit_code == 1 and "no restriction 'NOPE' (the feed has TSR-2026-101" in r.output
    # the old form still works; a mix of both is refused
    r = run("import", tmp_path / "r.csv", "--job", job, "--feed", feed.parent, "--replace")
    assert r.exit_code == 1 and "leave --feed and --time-zone out" in r.output
