"""Per train, a temporary restriction applies by the time the train passes: the one rule
(:func:`planner.line.operating_day.leg_restrictions`), the margins' rows for trains that pass while a
part-day restriction is lifted, and the conflict check's and train graph's runs of those trains."""
from __future__ import annotations

import dataclasses
import json
import textwrap
from datetime import date, datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from linedb import default_tables, quick_job, write_line_db
from planner.job.day import day_line, lifted_restrictions
from planner.line.daily import TemporaryRestriction
from planner.line.loader import load_line
from planner.line.operating_day import DayInputs, leg_restrictions, local_instant, operating_day
from planner.line.units import KMH

TZ = "Asia/Tokyo"
DAY = operating_day(date(2026, 11, 30), TZ, 3)  # 03:00 on the 30th to 03:00 on 1 December, local


def tsr(rid: str, start: str, until: str, a: float = 4800.0, b: float = 5200.0, kmh: float = 45.0,
        direction: str = "both", train_type=None) -> TemporaryRestriction:
    f = local_instant(datetime.fromisoformat(start), TZ)
    u = local_instant(datetime.fromisoformat(until), TZ, late=True)
    return TemporaryRestriction(rid, a, b, kmh * KMH, direction, train_type, start, until, f, u, "test", False)


PM = tsr("PM", "2026-11-30T12:00", "2026-12-02T05:00")  # part of the day: from noon on
WHOLE = tsr("WHOLE", "2026-11-29T12:00", "2026-12-02T05:00")


@pytest.fixture(scope="module")
def straight(tmp_path_factory):
    """A level, straight 10 km line without permanent restrictions, A at 200 m, B at 9800 m; train 101
    leaves A at 06:00 and 103 at 15:00 (local), both due at B 600 s later."""
    t = default_tables()
    t["line"]["end_m"] = 10000.0
    t["stations"] = pd.DataFrame([("A", "Aoba", 200.0, 230.0, 170.0, 200.0),
                                  ("B", "Bashi", 9800.0, 9830.0, 9770.0, 200.0)], columns=t["stations"].columns)
    for k in ("gradients", "curves", "speed_limits", "beacons", "signals"):
        t[k] = t[k].iloc[:0]
    t["timetable"] = pd.DataFrame([("101", "EMU10", "down", 0, "A", None, 21600.0, True),
                                   ("101", "EMU10", "down", 1, "B", 22200.0, None, True),
                                   ("103", "EMU10", "down", 0, "A", None, 54000.0, True),
                                   ("103", "EMU10", "down", 1, "B", 54600.0, None, True)],
                                  columns=t["timetable"].columns)
    del t["nodes"], t["edges"]
    return load_line(write_line_db(tmp_path_factory.mktemp("pt") / "straight", nodes=None, edges=None, **t))


def day(line, *restrictions) -> tuple:
    d = DayInputs(DAY, tuple(restrictions), tuple(t.train_id for t in line.trains))
    return day_line(line, d), d


def test_a_restriction_applies_when_in_force_at_some_instant_of_the_trains_run_of_the_leg(straight):
    # 101 runs A→B from 06:00 to 06:10 local (21:00Z to 21:10Z on the 29th)
    assert local_instant(datetime(2026, 11, 30, 6, 0), TZ) == 1795996800 - 3 * 3600
    rs = [PM, WHOLE,
          tsr("AM", "2026-11-30T06:05", "2026-12-02T05:00"),  # starts while the train is on the leg
          tsr("AT_ARRIVAL", "2026-11-30T06:10", "2026-12-02T05:00"),  # starts as it arrives: the safe side
          tsr("ENDED", "2026-11-29T05:00", "2026-11-30T06:00"),  # ends as it leaves: validity is half-open
          tsr("UP", "2026-11-30T05:00", "2026-11-30T07:00", direction="up"),
          tsr("EMU6", "2026-11-30T05:00", "2026-11-30T07:00", train_type="EMU6")]
    got = leg_restrictions(rs, DAY, straight, "EMU10", "down", "A", "B", 21600.0, 22200.0)
    assert [r.restriction_id for r in got] == ["WHOLE", "AM", "AT_ARRIVAL"]
    # 103 at 15:00: the afternoon ones; without times: every one that reaches the leg at some time of the day
    assert [r.restriction_id for r in leg_restrictions(rs, DAY, straight, "EMU10", "down", "A", "B", 54000.0,
                                                       54600.0)] == ["PM", "WHOLE", "AM", "AT_ARRIVAL"]
    assert [r.restriction_id for r in leg_restrictions(rs, DAY, straight, "EMU10", "down", "A", "B")] == [
        "PM", "WHOLE", "AM", "AT_ARRIVAL", "ENDED"]
    # a whole-day restriction applies to a train of the day whatever its times (one before 03:00, the day's start)
    assert leg_restrictions([WHOLE], DAY, straight, "EMU10", "down", "A", "B", 3600.0, 4200.0) == (WHOLE,)
    # a stretch outside the leg's window (stop markers 230..9830 m widened by the 200 m train + 1 m) does not
    # reach it; one that overlaps it by a metre does
    far = tsr("FAR", "2026-11-30T05:00", "2026-11-30T07:00", a=0.0, b=29.0)
    near = dataclasses.replace(far, restriction_id="NEAR", end_m=30.0)
    assert leg_restrictions([far, near], DAY, straight, "EMU10", "down", "A", "B", 21600.0, 22200.0) == (near,)


def test_only_the_trains_passing_while_a_part_day_restriction_is_lifted_have_it_lifted(straight):
    line, d = day(straight, PM)
    assert lifted_restrictions(line, d) == {("101", 0): ("PM",)}
    line, d = day(straight, WHOLE)
    assert lifted_restrictions(line, d) == {}


def dip_loss(line, train_type: str, a_m: float, b_m: float, kmh_limit: float) -> float:
    """Closed form of the speed dip (tests/test_day_compute.py checks its premise on this same line): from
    cruise v1 brake to v2 at the service brake b, run the stretch + the train's length at v2, accelerate back
    at no more than a; against cruising, (len + L)(1/v2 - 1/v1) + (v1 - v2)^2 / (2 v1) (1/b + 1/a)."""
    t = line.train_type(train_type)
    v1 = min(line.max_speed_ms, t.max_speed_ms) - t.speed_margin_ms
    v2 = kmh_limit * KMH - t.speed_margin_ms
    return ((b_m - a_m) + t.length_m) * (1 / v2 - 1 / v1) + (v1 - v2) ** 2 / (2 * v1) * (1 / t.service_brake_ms2 +
                                                                                       1 / t.max_accel_ms2)


def margins(line, lifted=None):
    from planner.report.margins import compute_margins

    return compute_margins(line, train_types=["EMU10"], conflicts=False, lifted=lifted)


def test_margins_compute_each_train_with_the_restrictions_in_force_as_it_passes(straight):
    static = margins(straight).rows
    (s,) = static[(static.direction == "down") & static.scheduled_running_time_s.notna()].itertuples()
    assert list(s.train_ids) == ["101", "103"] and list(s.restrictions) == []

    line, d = day(straight, PM)
    rep = margins(line, lifted_restrictions(line, d))
    rows = rep.rows[(rep.rows.direction == "down") & rep.rows.scheduled_running_time_s.notna()]
    by = {tuple(r.train_ids): r for r in rows.itertuples()}
    assert sorted(by) == [("101",), ("103",)]
    lifted, slowed = by[("101",)], by[("103",)]
    # 06:00, before noon: computed without PM, exactly the static line's minimum and margin
    assert list(lifted.restrictions) == [] and lifted.min_running_time_s == s.min_running_time_s
    assert lifted.margin_s == s.margin_s and lifted.degraded_min_running_time_s == s.degraded_min_running_time_s
    # 15:00: the slower minimum, by at least the closed form of the dip
    loss = dip_loss(straight, "EMU10", PM.start_m, PM.end_m, 45.0)
    assert list(slowed.restrictions) == ["PM"]
    assert loss <= slowed.min_running_time_s - s.min_running_time_s <= loss * 1.25 + 5.0
    # the interstation row without trains is the day's line (every restriction that reaches it)
    (empty,) = rep.rows[(rep.rows.direction == "up")].itertuples()
    assert list(empty.restrictions) == ["PM"] and empty.n_trains == 0
    # per-train totals follow their own rows
    tot = rep.totals[rep.totals.level == "train"].set_index("train_id")
    assert tot.loc["101", "min_running_time_s"] == s.min_running_time_s
    assert tot.loc["103", "min_running_time_s"] == slowed.min_running_time_s


def test_whole_day_restrictions_compute_as_before(straight):
    line, d = day(straight, WHOLE)
    lifted = lifted_restrictions(line, d)
    a, b = margins(line, lifted).rows, margins(line).rows
    pd.testing.assert_frame_equal(a, b)
    (r,) = a[(a.direction == "down") & a.scheduled_running_time_s.notna()].itertuples()
    assert list(r.train_ids) == ["101", "103"] and list(r.restrictions) == ["WHOLE"]


def test_the_train_graph_and_conflict_runs_use_each_trains_restrictions(straight):
    from planner.network.arrivals import SimulatorCurves, build_trajectory, train_curves
    from planner.report.train_graph import train_paths

    line, d = day(straight, PM)
    src = train_curves(line, lifted_restrictions(line, d))
    t101, t103 = line.trains
    for train, alone in ((t101, straight), (t103, line)):  # 101 runs as on the static line, 103 as on the day's
        got = build_trajectory(line, train, src)
        want = build_trajectory(alone, train, SimulatorCurves(alone))
        assert np.array_equal(got.t_s, want.t_s) and np.array_equal(got.u_m, want.u_m)
    # with the restriction the run is slower through the stretch (the same scheduled time: lower speed there)
    on = build_trajectory(line, t103, src)
    off = build_trajectory(line, t101, src)
    stretch = (float(on.front_time(PM.end_m) - on.front_time(PM.start_m)),
               float(off.front_time(PM.end_m) - off.front_time(PM.start_m)))
    assert stretch[0] >= (PM.end_m - PM.start_m) / (45.0 * KMH) - 1e-6 > stretch[1]
    paths = {p.train_id: p for p in train_paths(line, src)}
    plain = {p.train_id: p for p in train_paths(straight)}
    assert np.array_equal(paths["101"].t_s, plain["101"].t_s)
    assert not np.array_equal(paths["103"].t_s - (54000.0 - 21600.0), plain["101"].t_s)


# --------------------------------------------------------------------------- end to end, with a track network
@pytest.fixture(scope="module")
def project(tmp_path_factory):
    from test_daily_feed import calendar_rows, write_feed

    root = tmp_path_factory.mktemp("pt_run")
    # the tiny line with a stop node at each of its stations (one track), so the conflict check runs
    nodes = pd.DataFrame([("N1", "boundary", 0.0, "IXL1", None, "1"), ("N2", "stop", 200.0, "IXL1", "A", "1"),
                          ("N3", "stop", 2500.0, "IXL1", "B", "1"), ("N4", "stop", 4800.0, "IXL2", "C", "1"),
                          ("N5", "end", 5000.0, "IXL2", None, "1")],
                         columns=["node_id", "kind", "position_m", "interlocking", "station_id", "track"])
    edges = pd.DataFrame([(f"E{i}", f"N{i}", f"N{i + 1}", b - a, "1") for i, (a, b) in
                          enumerate([(0.0, 200.0), (200.0, 2500.0), (2500.0, 4800.0), (4800.0, 5000.0)], 1)],
                         columns=["edge_id", "from_node", "to_node", "length_m", "track"])
    write_line_db(root / "lines" / "tiny", nodes=nodes, edges=edges)
    # on A-B, from 06:05 on the 30th: 101 (A 06:00 → B 06:03:20) passes before it, 202 (C 06:06:40 → A) after
    r1 = dict(restriction_id="R1", start_m=1000.0, end_m=1400.0, limit_kmh=45.0, direction="both", train_type=None,
              valid_from="2026-11-30T06:05", valid_until="2026-12-02T05:00", reason="renewal", has_beacon=False)
    write_feed(root / "feeds" / "tiny", restrictions=[r1], **calendar_rows())
    (root / "jobs").mkdir()
    (root / "jobs" / "job.toml").write_text(quick_job([root / "lines" / "tiny"], root / "out") + textwrap.dedent(f"""
        [day]
        time_zone = "Asia/Tokyo"
        feeds = ["{root / 'feeds' / 'tiny'}"]
    """))
    from planner.job.config import load_job
    from planner.job.day import with_day
    from planner.job.pipeline import run_job

    out = {}
    for d in ("2026-11-27", "2026-11-30"):  # a Friday before R1, the Monday it starts
        s = run_job(with_day(load_job(root / "jobs" / "job.toml"), d), show_progress=False)
        out[d] = Path(s.run_dir)
    return out


def _dataset(run: Path, name: str) -> pd.DataFrame:
    return pd.read_parquet(run / name)  # with its partition columns (line=, direction=, ...)


def test_a_run_computes_trains_passing_while_lifted_without_the_restriction(project):
    before, monday = project["2026-11-27"], project["2026-11-30"]
    day_rec = json.loads((monday / "manifest.json").read_text())["operating_day"]["lines"][0]
    assert [(r["restriction_id"], r["whole_day"]) for r in day_rec["restrictions"]] == [("R1", False)]
    m0, m1 = _dataset(before, "margins"), _dataset(monday, "margins")

    def row(m, tid, origin):
        (r,) = [r for r in m.itertuples() if tid in list(r.train_ids) and r.origin == origin]
        return r

    # 101 passes A-B before 06:05: its row is computed without R1, as on the Friday (nothing in force)
    a, b = row(m0, "101", "A"), row(m1, "101", "A")
    assert list(b.restrictions) == [] and b.min_running_time_s == pytest.approx(a.min_running_time_s, abs=1e-9)
    # 202 (C→A, through B) passes after: slower, with R1
    a, b = row(m0, "202", "C"), row(m1, "202", "C")
    assert list(b.restrictions) == ["R1"]
    assert b.min_running_time_s > a.min_running_time_s
    # the interstation row without trains has R1 (the day's line)
    (r,) = [r for r in m1.itertuples() if r.direction == "down" and r.train_type == "EMU10" and r.origin == "A"
            and r.n_trains == 0]
    assert list(r.restrictions) == ["R1"] and r.min_running_time_s > row(m1, "101", "A").min_running_time_s
    # the conflict check's blocking windows: 101's as on the Friday, 202's later
    o0, o1 = _dataset(before, "occupation"), _dataset(monday, "occupation")
    cols = [c for c in o0.columns if c not in ("run_id", "run_date")]
    k0, k1 = o0[o0.train_id == "101"][cols].reset_index(drop=True), o1[o1.train_id == "101"][cols].reset_index(drop=True)
    pd.testing.assert_frame_equal(k0, k1)
    w0, w1 = o0[o0.train_id == "202"], o1[o1.train_id == "202"]
    times = ["entry_s", "exit_s", "clear_s"]
    assert len(w0) == len(w1) and not np.array_equal(w0[times].to_numpy(), w1[times].to_numpy())
    # the restrictions page names the trains computed without it
    page = (monday / "report" / "tiny_restrictions.html").read_text()
    assert "without R1" in page and "understated" not in page
    # the margin report names the restriction a row's trains run with
    report = (monday / "report" / "tiny_margins.html").read_text()
    assert "(with R1)" in report and "(with R1)" not in (before / "report" / "tiny_margins.html").read_text()


def test_the_train_timetable_takes_each_trains_own_row(straight):
    from planner.report.train_timetable import leg_runs, timetable_rows

    line, d = day(straight, PM)
    rows = margins(line, lifted_restrictions(line, d)).rows
    runs = leg_runs(line, rows)
    ends = {r["train_id"]: r for r in timetable_rows(line, runs) if r["station_id"] == "B"}
    plain = {r["train_id"]: r for r in timetable_rows(straight, leg_runs(straight, margins(straight).rows))
             if r["station_id"] == "B"}
    # 101 passes before noon: its leg is the static line's (its minimum arrival too), on a chart of its own
    assert ends["101"]["leg_min_running_time_s"] == plain["101"]["leg_min_running_time_s"]
    assert ends["101"]["minimum_arrival_s"] == plain["101"]["minimum_arrival_s"]
    assert ends["101"]["chart"].endswith("_600s_without-PM.html") and ends["103"]["chart"].endswith("_600s.html")
    assert ends["103"]["minimum_arrival_s"] > plain["103"]["minimum_arrival_s"]


def test_the_changes_between_runs_keep_a_legs_rows_apart():
    from planner.report.changes import _legs_by_key

    leg = dict(direction="down", train_type="E10", origin="A", destination="B", scheduled_running_time_s=165.0)
    frame = pd.DataFrame([{**leg, "restrictions": ["PM", "W"], "min_running_time_s": 218.0},
                          {**leg, "restrictions": ["W"], "min_running_time_s": 160.0}])
    got = _legs_by_key(frame)
    key = ("down", "E10", "A", "B", 165.0)
    # the row of the trains meeting every restriction keeps the leg's key (it compares with another day's row)
    assert got[key]["min_running_time_s"] == 218.0 and got[key + ("without PM",)]["min_running_time_s"] == 160.0
    assert _legs_by_key(frame.drop(columns="restrictions").iloc[:1]) == {key: {**leg, "min_running_time_s": 218.0}}


def test_a_restriction_on_one_track_reaches_the_trains_routed_over_it_only():
    """A double line whose down main is used both ways (B:main) beside the up main (U:2): the down train runs
    on B:main, the up train crosses to U:2 for 1600 … 400 m. A restriction on U:2 is lifted for the down train,
    one on B:main over the same stretch for the up train; one on no named track reaches both (as before)."""
    from test_network import _both_ways_main

    line = _both_ways_main()
    on_up = dataclasses.replace(tsr("ON_U2", "2026-11-29T12:00", "2026-12-02T05:00", a=600.0, b=1400.0),
                                track="U:2")
    on_main = dataclasses.replace(on_up, restriction_id="ON_MAIN", track="B:main")
    anywhere = dataclasses.replace(on_up, restriction_id="ANY", track=None)
    d = DayInputs(DAY, (on_up, on_main, anywhere), ("T1", "T2"))
    assert lifted_restrictions(line, d) == {("T1", 0): ("ON_U2",), ("T2", 0): ("ON_MAIN",)}


def test_the_graphs_restriction_blocks_are_on_the_timetables_clock_within_the_day(straight):
    """09:00-15:00 local is 32400-54000 s on the trains' clock; one in force since the day before starts at the
    day's 03:00 start (10800 s); one running past the day's end stops at 03:00 next day (97200 s)."""
    from planner.bundle.manifest import BundleDay
    from planner.job.day import restriction_blocks

    rs = (tsr("MID", "2026-11-30T09:00", "2026-11-30T15:00", direction="down"), WHOLE)
    line, _ = day(straight, *rs)
    bday = BundleDay("2026-11-30", TZ, DAY.start_s, DAY.end_s,
                     tuple((r.restriction_id, r.valid_from_s, r.valid_until_s) for r in rs))
    assert restriction_blocks(line, bday) == [("MID", 4800.0, 5200.0, 32400.0, 54000.0, 45.0, "down"),
                                              ("WHOLE", 4800.0, 5200.0, 10800.0, 97200.0, 45.0, "both")]
    assert restriction_blocks(line, None) == []
