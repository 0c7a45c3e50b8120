"""The predicted day on the sample line: its restricted day 2026-11-30, and the line without restrictions."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner.delay.network import ARRIVAL, DEPARTURE, DWELL, HEADWAY
from planner.delay.predicted import predict_day
from planner.line.loader import load_line
from planner.network.arrivals import train_curves
from planner.network.check import check_timetable

ROOT = Path(__file__).resolve().parents[1]
MIN_DWELL = 20.0


@pytest.fixture(scope="module")
def restricted():
    from planner.job.config import load_job
    from planner.job.day import line_on_day

    job = load_job(ROOT / "jobs" / "nightly.toml")  # plans 2026-11-30: three restrictions in force
    on, _said, lifted = line_on_day(job, load_line(ROOT / "lines" / "sample"))
    check = check_timetable(on, {}, curves=train_curves(on, lifted))
    return check, predict_day(check, min_dwell_s=MIN_DWELL)


def test_no_train_departs_before_it_arrives_or_before_its_minimum_dwell(restricted):
    check, day = restricted
    net, t = day.net, day.predicted_s
    dw = np.flatnonzero(net.act_kind == DWELL)
    arr, dep = net.act_src[dw], net.act_dst[dw]
    assert np.all(net.ev_kind[arr] == ARRIVAL) and np.all(net.ev_kind[dep] == DEPARTURE)
    assert np.all(t[dep] >= t[arr] + MIN_DWELL - 1e-9)
    assert np.all(t >= net.sched_s)  # nor before its schedule
    # what the conflict check computed alone lets some leave before the minimum dwell (1013D at HGO: 0 s)
    assert np.any(net.plan_s[dep] < net.plan_s[arr] + MIN_DWELL)


def test_1013D_carries_its_delay_from_HGO_by_hand(restricted):
    _check, day = restricted
    net = day.net
    k = net.train_ids.index("1013D")
    ev = np.flatnonzero(net.ev_train == k)
    st = [net.ev_station[e] for e in ev]
    i = st.index("HGO")  # the arrival at HGO
    run = next(a for a in range(net.n_activities) if net.act_dst[a] == ev[i])
    # by hand: it leaves KWB on time and needs the leg's minimum (a restriction in force): late at HGO by
    # the minimum − the scheduled running time, then leaves HGO the minimum dwell after arriving
    sched_run = net.sched_s[ev[i]] - net.sched_s[ev[i - 1]]
    assert day.delay_s[ev[i - 1]] == 0.0
    assert day.delay_s[ev[i]] == pytest.approx(net.min_s[run] - sched_run, abs=1e-9)
    assert day.delay_s[ev[i]] > 50.0
    assert day.predicted_s[ev[i + 1]] == pytest.approx(day.predicted_s[ev[i]] + MIN_DWELL, abs=1e-9)
    assert day.cause[ev[i]] == run


def test_a_day_without_restrictions_is_late_only_where_the_timetable_conflicts():
    line = load_line(ROOT / "lines" / "sample")
    check = check_timetable(line, {}, curves=train_curves(line))
    day = predict_day(check, min_dwell_s=MIN_DWELL)
    late = {day.net.train_ids[int(k)] for k in day.net.ev_train[day.delay_s > 1e-9]}
    held = {r["train_b"] for r in check.conflicts}
    assert held, "the sample's full timetable has conflicts"
    assert late <= held
    # each held train is late by what its conflict asks at most (headways here give exactly the wait)
    by_train = {}
    for r in check.conflicts:
        by_train[r["train_b"]] = max(by_train.get(r["train_b"], 0.0), r["delay_s"])
    for tid in late:
        k = day.net.train_ids.index(tid)
        assert day.delay_s[day.net.ev_train == k].max() <= by_train[tid] + 1e-6
    assert (day.net.act_kind == HEADWAY).sum() > 0
