"""What is in force is what is computed: the day's line (temporary restrictions added, only the trains that
run), the units' cache keys, and the minimum running time against a closed form for the speed dip."""
from __future__ import annotations

import dataclasses
from datetime import date

import numpy as np
import pandas as pd
import pytest

from linedb import default_tables, write_line_db
from planner.api import running_time
from planner.job.day import day_line, line_digest
from planner.job.publish import digest
from planner.job.units import interstation_digest, interstation_inputs
from planner.line.daily import TemporaryRestriction
from planner.line.loader import load_line
from planner.line.model import DIRECTIONS
from planner.line.operating_day import DayInputs, operating_day
from planner.line.units import KMH

DAY = operating_day(date(2026, 11, 30), "Asia/Tokyo", 3)


def tsr(rid: str, a: float, b: float, kmh: float, direction: str = "both", train_type=None) -> TemporaryRestriction:
    return TemporaryRestriction(rid, a, b, kmh * KMH, direction, train_type, "2026-11-30T01:00", "2026-12-02T05:00",
                                DAY.start_s - 7200, DAY.end_s + 7200, "test", False, row=7)


def day_of(line, *restrictions, trains=None) -> DayInputs:
    ids = tuple(t.train_id for t in line.trains) if trains is None else trains
    return DayInputs(DAY, tuple(restrictions), ids)


def unit_keys(line) -> dict:
    types = [t.train_type for t in line.train_types]
    return {(t, d, a.station_id, b.station_id): interstation_digest(line, t, a.station_id, b.station_id)
            for t in types for d in DIRECTIONS for a, b in line.interstations(d)}


@pytest.fixture
def tiny(tmp_path):
    return load_line(write_line_db(tmp_path / "tiny", nodes=None, edges=None))


def test_a_restriction_changes_the_key_of_exactly_the_units_it_reaches(tiny):
    base = unit_keys(day_line(tiny, day_of(tiny)))
    assert len(base) == 8  # 2 types x 2 directions x (A-B, B-C)
    # 3000-3200 m, down, EMU6 only: inside B (2500) - C (4800), far from A-B's window (its stop markers + 121 m)
    one = unit_keys(day_line(tiny, day_of(tiny, tsr("W", 3000.0, 3200.0, 45.0, "down", "EMU6"))))
    assert [k for k in base if base[k] != one[k]] == [("EMU6", "down", "B", "C")]
    # both directions, every type, over A-B: 4 units
    two = unit_keys(day_line(tiny, day_of(tiny, tsr("X", 1000.0, 1100.0, 45.0))))
    assert sorted(k for k in base if base[k] != two[k]) == sorted(
        (t, d, *(("A", "B") if d == "down" else ("B", "A"))) for t in ("EMU10", "EMU6") for d in DIRECTIONS)


def test_the_slice_a_unit_sees_is_digested_once_per_line_and_an_edited_line_is_digested_afresh(tiny):
    """interstation_digest keeps a line's slices' digests (the tables', stops', margins' and charts' keys digest
    the same slice): each is the digest of interstation_inputs, asked again it is the same, and a line with a
    lowered limit (another, immutable, line object) gets its own digests, not the first line's."""
    keys = unit_keys(tiny)
    assert keys == {k: digest(interstation_inputs(tiny, k[0], k[2], k[3])) for k in keys} == unit_keys(tiny)
    lim = tiny.speed_limits[0]
    slower = dataclasses.replace(tiny, speed_limits=(dataclasses.replace(lim, limit_ms=lim.limit_ms - 1.0),)
                                 + tiny.speed_limits[1:])
    moved = unit_keys(slower)
    assert moved == {k: digest(interstation_inputs(slower, k[0], k[2], k[3])) for k in keys}
    assert any(moved[k] != keys[k] for k in keys)


def test_a_units_key_does_not_depend_on_the_restrictions_place_in_the_feed_or_its_validity(tiny):
    w = tsr("W", 3000.0, 3200.0, 45.0)
    a = unit_keys(day_line(tiny, day_of(tiny, tsr("X", 1000.0, 1100.0, 45.0), w)))
    moved = dataclasses.replace(w, row=0, valid_until="2026-12-09T05:00", valid_until_s=w.valid_until_s + 7 * 86400)
    b = unit_keys(day_line(tiny, day_of(tiny, moved, tsr("X", 1000.0, 1100.0, 45.0))))
    assert a == b


def test_the_days_line_runs_only_its_trains_and_keys_the_line_units_by_them(tiny):
    everyone = day_line(tiny, day_of(tiny))
    only = day_line(tiny, day_of(tiny, trains=("101",)))
    assert [t.train_id for t in only.trains] == ["101"] and only.source_digest == tiny.source_digest
    assert line_digest(only) != line_digest(everyone)
    assert line_digest(day_line(tiny, day_of(tiny))) == line_digest(everyone)
    assert line_digest(day_line(tiny, day_of(tiny, tsr("W", 3000.0, 3200.0, 45.0)))) != line_digest(everyone)


@pytest.fixture
def straight(tmp_path):
    """A level, straight 10 km line without permanent restrictions: A at 200 m, B at 9800 m."""
    t = default_tables()
    t["line"]["end_m"] = 10000.0
    t["stations"] = pd.DataFrame([("A", "Aoba", 200.0, 230.0, 170.0, 200.0),
                                  ("B", "Bashi", 9800.0, 9830.0, 9770.0, 200.0)],
                                 columns=t["stations"].columns)
    t["gradients"] = t["gradients"].iloc[:0]
    t["curves"] = t["curves"].iloc[:0]
    t["speed_limits"] = t["speed_limits"].iloc[:0]
    t["beacons"] = t["beacons"].iloc[:0]
    t["signals"] = t["signals"].iloc[:0]
    t["timetable"] = pd.DataFrame([("101", "EMU10", "down", 0, "A", None, 21600.0, True),
                                   ("101", "EMU10", "down", 1, "B", 22200.0, None, True)],
                                  columns=t["timetable"].columns)
    del t["nodes"], t["edges"]
    return load_line(write_line_db(tmp_path / "straight", nodes=None, edges=None, **t))


@pytest.mark.parametrize("train_type,kmh_limit", [("EMU10", 45.0), ("EMU10", 25.0), ("EMU10", 60.0)])
def test_the_minimum_running_time_rises_by_at_least_the_speed_dip(straight, train_type, kmh_limit):
    """Closed form: at cruise v1 the train brakes to v2 at the service (intermediate) brake b, runs the
    restricted length + its own length at v2 and accelerates back at no more than its maximum acceleration
    a; against running at v1 that loses (len + L)(1/v2 - 1/v1) + (v1 - v2)^2 / (2 v1) (1/b + 1/a)."""
    a_m, b_m = 4800.0, 5200.0
    train = straight.train_type(train_type)
    v1 = min(straight.max_speed_ms, train.max_speed_ms) - train.speed_margin_ms
    v2 = kmh_limit * KMH - train.speed_margin_ms
    b, acc = train.service_brake_ms2, train.max_accel_ms2
    loss = ((b_m - a_m) + train.length_m) * (1 / v2 - 1 / v1) + (v1 - v2) ** 2 / (2 * v1) * (1 / b + 1 / acc)
    before = running_time(day_line(straight, day_of(straight)), train_type, "A", "B")
    after = running_time(day_line(straight, day_of(straight, tsr("W", a_m, b_m, kmh_limit))), train_type, "A", "B")
    # the closed form's premise: without the restriction the train cruises at v1 over the whole dip
    c = before.curve
    x = c["position_m"]
    dip = (x > a_m - v1 ** 2 / (2 * b) - 10) & (x < b_m + train.length_m + v1 ** 2 / (2 * acc))
    assert np.allclose(c.loc[dip, "speed_kmh"], v1 / KMH, atol=0.2)
    assert after.curve["speed_kmh"][(after.curve["position_m"] > a_m) &
                                    (after.curve["position_m"] < b_m + train.length_m)].max() <= v2 / KMH + 1e-6
    gained = after.time_s - before.time_s
    # at least the physical loss; the real acceleration (traction minus resistance) is below a, so a little more
    assert loss <= gained <= loss * 1.25 + 5.0, (gained, loss)
    print(f"{train_type} {kmh_limit}: gained {gained:.2f} s, closed form {loss:.2f} s")


def test_the_restrictions_page_names_the_legs_slowed_and_the_trains_that_lose_their_margin(straight):
    from planner.pages.restrictions import render
    from planner.report.restriction_effects import restriction_losses, scheduled_legs

    line = day_line(straight, day_of(straight, tsr("W", 4800.0, 5200.0, 45.0)))
    before = running_time(straight, "EMU10", "A", "B").time_s
    after = running_time(line, "EMU10", "A", "B").time_s
    (leg,) = [x for x in restriction_losses(line)["W"] if x[0] == "EMU10" and x[1] == "down"]
    assert leg[:4] == ("EMU10", "down", "A", "B") and leg[4] == pytest.approx(after - before, abs=1e-6)
    # 10 s of margin without the restriction, about 40 s lost with it: the train loses its margin;
    # 100 s of margin: it still makes it
    rows = pd.DataFrame([dict(train_type="EMU10", direction="down", origin="A", destination="B", n_trains=1,
                              train_ids=["101"], scheduled_running_time_s=s, remaining_margin_s=0.0,
                              arrival_error_s=0.0, arrival_error_degraded_s=0.0) for s in (before + 10, before + 100)])
    legs = scheduled_legs(line, rows)
    assert [round(x["margin_before_s"], 6) for x in legs] == [10.0, 100.0]
    assert legs[0]["margin_after_s"] == pytest.approx(10 + before - after) and legs[0]["margin_after_s"] < 0
    page = render(line, {"day": "2026-11-30", "restrictions": [
        dict(restriction_id="W", start_m=4800.0, end_m=5200.0, limit_kmh=45.0, direction="both", train_type=None,
             valid_from="2026-11-30T01:00", valid_until="2026-12-02T05:00", whole_day=True, has_beacon=False,
             reason="test")]}, rows)
    assert "1 leg row(s), 1 train run(s) lose their margin" in page and "still makes it" in page
    assert f"EMU10 A→B: +{after - before:.1f} s" in page
