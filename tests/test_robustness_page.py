"""The robustness page (``planner.pages.robustness``) from synthetic frames: its sections, the late train and why,
escaping, no simulated day, the same bytes twice, and its size for a realistic day (350 trains × 20 stops)."""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd

from planner.pages.robustness import render, write_page

TYPES = ("E6", "E8", "E10")
CAUSE = "its run from S1 needs 218.0 s, 165.0 s scheduled"


def frames(n_trains: int = 3, n_stations: int = 4, names=None, days: int = 500, seed: int = 3):
    """(summary, trains, stations, activities, events) of a made-up day: trains alternate down and up over
    ``n_stations`` stations 2.5 km apart, types E6, E8, E10 in turn; the first train loses 53 s on its run into
    the third station (the cause of its delay), the next train of its direction is held by it there."""
    rng = np.random.default_rng(seed)
    names = list(names or [f"Station {i}" for i in range(n_stations)])
    sids = [f"S{i}" for i in range(n_stations)]
    ev, tr, acts = [], [], []
    for k in range(n_trains):
        tid, d, tt = f"T{k}", ("down", "up")[k % 2], TYPES[k % 3]
        order = list(range(n_stations)) if d == "down" else list(range(n_stations))[::-1]
        t0 = 18000.0 + 240.0 * (k // 2)
        delay = 0.0
        calls = []
        for j, i in enumerate(order):
            arr = None if j == 0 else t0 + j * 180.0 - 30.0
            dep = None if j == n_stations - 1 else t0 + j * 180.0
            calls += [(j, i, "arrival", arr)] if arr is not None else []
            calls += [(j, i, "departure", dep)] if dep is not None else []
        for seq, i, kind, t in calls:
            cause = ""
            if k == 0 and seq == 2 and kind == "arrival":
                delay, cause = 53.0, CAUSE.replace("S1", sids[order[1]])
            elif k == 2 and seq == 2 and kind == "arrival":
                delay, cause = 12.5, f"held by T0 at section U1-012/1 ({names[i]}, track U1)"
            elif kind == "departure" and delay > 0:
                delay = max(0.0, delay - 15.0)
            ev.append({"train_id": tid, "train_type": tt, "direction": d, "seq": seq, "station_id": sids[i],
                       "event": kind, "scheduled_s": t, "predicted_s": t + delay, "delay_s": delay,
                       "own_delay_s": delay if k != 2 else 0.0, "knock_on_s": 0.0 if k != 2 else delay, "cause": cause})
            mean = float(rng.uniform(2, 60)) + delay
            ko = float(rng.uniform(0, 0.3)) * mean
            p50 = 10.0 * np.ceil(mean * 0.7 / 10)
            w60 = float(np.clip(1.0 - mean / 150.0, 0.2, 1.0))
            tr.append({"train_id": tid, "train_type": tt, "direction": d, "seq": seq, "station_id": sids[i],
                       "station_name": names[i], "event": kind, "scheduled_s": t, "predicted_delay_s": delay,
                       "mean_delay_s": mean, "sem_s": mean / 40.0, "p50_s": p50, "p90_s": p50 + 60.0,
                       "p99_s": p50 + 160.0, "within_60s": w60, "within_180s": min(1.0, w60 + 0.08),
                       "within_300s": min(1.0, w60 + 0.1), "knock_on_s": ko, "primary_s": mean / 5.0})
        for j in range(n_stations - 1):
            a, b = sids[order[j]], sids[order[j + 1]]
            slack = -53.0 if (k == 0 and j == 1) else float(rng.uniform(5, 30))
            acts.append({"activity": "run", "from_train": tid, "to_train": tid, "from_station": a, "to_station": b,
                         "place": "", "min_s": 150.0 - slack, "slack_s": slack, "transmitted_s": float(rng.uniform(0, 30)),
                         "binding_share": float(rng.uniform(0, 1)), "absorbed_s": max(0.0, slack) * 0.4})
            if j:
                acts.append({"activity": "dwell", "from_train": tid, "to_train": tid, "from_station": a,
                             "to_station": a, "place": "", "min_s": 20.0, "slack_s": 10.0, "transmitted_s": 5.0,
                             "binding_share": 0.3, "absorbed_s": 2.0})
        if k >= 2:
            i = order[2]
            acts.append({"activity": "headway", "from_train": f"T{k - 2}", "to_train": tid, "from_station": sids[i],
                         "to_station": sids[i], "place": f"section U1-012/1 ({names[i]}, track U1)", "min_s": 90.0,
                         "slack_s": 150.0, "transmitted_s": float(rng.uniform(0, 15)), "binding_share": 0.2,
                         "absorbed_s": 3.0})
    trains, events, activities = pd.DataFrame(tr), pd.DataFrame(ev), pd.DataFrame(acts)
    arr = trains[trains.event == "arrival"]
    st = []
    for (d, sid), g in arr.groupby(["direction", "station_id"], sort=True):
        i = sids.index(sid)
        st.append({"direction": d, "station_id": sid, "station_name": names[i], "position_m": 200.0 + 2500.0 * i,
                   "arrivals": len(g), **{c: float(g[c].mean()) for c in
                                          ("within_60s", "within_180s", "within_300s", "mean_delay_s", "knock_on_s")}})
    stations = pd.DataFrame(st)
    summary = {"days": days, "seed": 7, "rules": ["origin, every train type: 30% of events late by an exponential "
                                                  "delay of mean 60 s"],
               "trains": n_trains, "events": len(events), "activities": len(activities), "day": "2026-11-30",
               "restrictions": ["TSR-2026-101"], "dropped": 0, "knock_on_conflicts": 1 if n_trains > 2 else 0,
               "knock_on_places": [f"{names[order[2]]} section U1-012/1"] if n_trains > 2 else [],
               "min_dwell_s": 20.0}
    return summary, trains, stations, activities, events


def page(**kw) -> str:
    s, tr, st, acts, ev = frames(**kw)
    return render("Sample Line", s, tr, st, acts, ev, nav="<p class='sub nav'><a href='../index.html'>overview</a></p>")


def test_every_section_is_there_with_the_head_figures():
    html = page()
    for anchor in ("punctuality", "predicted", "spread", "distribution", "margins", "read"):
        assert f"id='{anchor}'" in html, anchor
    assert "Sample Line" in html and "2026-11-30" in html and "500 simulated days" in html and "seed 7" in html
    assert "30% of events late by an exponential delay of mean 60 s" in html
    assert "of the line&#x27;s arrivals at most 1 min late" in html
    assert "knock-on conflicts on the predicted day" in html
    assert "<a href='../index.html'>overview</a>" in html  # the nav line as given
    # the chart: an SVG per page, three lines a direction, station names on it, parsable as XML
    svgs = re.findall(r"<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=.*?</svg>", html, re.S)
    chart = ET.fromstring(svgs[0])
    texts = "".join(chart.itertext())
    assert "Station 0" in texts and "Station 3" in texts and "down" in texts and "up" in texts
    assert sum(1 for e in chart.iter() if e.tag.endswith("polyline")) == 6
    assert "Headways and connections passing on the most delay" in html and "T0</b> → <b>T2" in html
    assert html.count("<details><summary><span><b>T") == 3  # a line per train in the distributions
    assert "mean absorbed [s/day]" in html


def test_the_late_train_and_its_cause_are_named():
    html = page()
    pred = html[html.index("id='predicted'"):html.index("id='spread'")]
    assert "T0" in pred and "its run from S1 needs 218.0 s, 165.0 s scheduled" in pred
    assert "held by T0 at section U1-012/1 (Station 2, track U1)" in pred
    assert "05:05:30" in pred and "05:06:23" in pred  # scheduled and predicted of T0 at its third stop
    assert "53.0" in pred and "2 of 3 trains are late" in pred
    assert "largest delay 53.0 s at Station 2 (arrival)" in pred


def test_a_hostile_name_is_escaped_everywhere():
    bad = "<script>alert('x')</script>"
    s, tr, st, acts, ev = frames(names=["Minato", bad, "Kawa & <b>", "Senzan"])
    s["rules"] = ["<img src=x onerror=alert(1)>"]
    s["knock_on_places"] = [bad]
    ev["train_id"] = ev["train_id"].replace("T0", "<T0>")
    html = render("<Line>", s, tr, st, acts, ev)
    assert "<script" not in html and "<img" not in html and "<b>Kawa" not in html and "<Line>" not in html
    assert "&lt;script&gt;" in html and "&lt;Line&gt;" in html and "&lt;T0&gt;" in html
    for svg in re.findall(r"<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=.*?</svg>", html, re.S):
        ET.fromstring(svg)


def test_no_simulated_day_still_shows_the_predicted_day():
    s, _, _, _, ev = frames()
    s["days"] = 0
    for empty in (None, pd.DataFrame()):
        html = render("Sample Line", s, empty, empty, empty, ev)
        assert "The Monte Carlo did not run" in html and "no simulated day" in html
        assert "<svg" not in html
        assert CAUSE in html and "T0" in html
        assert "id='distribution'" in html and "id='read'" in html
    html = render("Sample Line", {}, None, None, None, None)  # nothing at all
    assert "No event: no train runs on this day." in html and "The Monte Carlo did not run" in html


def test_the_same_inputs_give_the_same_bytes(tmp_path):
    s, tr, st, acts, ev = frames(n_trains=12, n_stations=6)
    one = render("Sample Line", s, tr, st, acts, ev)
    assert render("Sample Line", s, tr.sample(frac=1.0, random_state=1), st, acts, ev) == one  # row order
    out = write_page(tmp_path / "report" / "sample_robustness.html", "Sample Line", s, tr, st, acts, ev)
    assert out.read_bytes() == one.encode("utf-8")
    assert not str(tmp_path) in one


def test_a_realistic_day_keeps_the_page_small_and_says_what_it_leaves_out():
    s, tr, st, acts, ev = frames(n_trains=350, n_stations=21)  # 20 stops after the origin
    ev.loc[ev.event == "arrival", "cause"] = "its run needs 1.0 s more"
    ev.loc[ev.event == "arrival", "delay_s"] = 1.0 + ev.index[ev.event == "arrival"] / 1000.0
    html = render("Sample Line", s, tr, st, acts, ev)
    assert len(html.encode("utf-8")) < 2_000_000
    assert "The 30 latest of 350 late trains; 320 more are in the dataset" in html
    assert html.count("<details><summary><span><b>T") == 350
    assert "The other" in html  # the margins table's further legs


def test_each_trains_distribution_line_and_stops_read_as_written():
    """A train's line shows its destination's figures (a p90 over 3 min in red, a share as a percent, a mean that
    rounds to zero without its sign, a missing percentile as a dash); its stops are its departure and its arrivals,
    not the departures on the way; a train with no arrival has dashes; trains in order of departure."""
    from planner.pages.robustness import _distribution
    from planner.pages.robustness_share import RobustnessShare, _distribution as trains_of

    nan = float("nan")
    cols = ("train_id", "train_type", "direction", "seq", "station_name", "event", "scheduled_s", "mean_delay_s",
            "p50_s", "p90_s", "p99_s", "within_60s", "within_180s", "within_300s", "knock_on_s", "predicted_delay_s")
    rows = [("A1", "E6", "down", 0, "X", "departure", 21600.0, 1.0, 0.0, 10.0, 20.0, 1.0, 1.0, 1.0, 0.0, 0.0),
            ("A1", "E6", "down", 1, "Y", "departure", 21810.0, 2.0, 0.0, 10.0, 20.0, 1.0, 1.0, 1.0, 0.0, 0.0),
            ("A1", "E6", "down", 1, "Y", "arrival", 21780.0, 2.5, 0.0, 10.0, 20.0, 0.5, 1.0, 1.0, 0.0, 1.0),
            ("A1", "E6", "down", 2, "Z & Co", "arrival", 22050.0, -0.01, 0.0, 185.4, nan, 0.934, 1.0, 1.0, 12.345,
             3.0),
            ("B2", "E6", "down", 0, "X", "departure", 18000.0, 4.0, 0.0, 10.0, 20.0, 1.0, 1.0, 1.0, 0.0, 0.0)]
    tr = pd.DataFrame(rows, columns=cols)
    html = "".join(_distribution([RobustnessShare(trains_rows=len(tr), dist=trains_of(tr))], 100))
    a1 = html[html.index("<b>A1</b>"):]
    assert a1.startswith("<b>A1</b></span><span>down</span><span>X → Z &amp; Co</span><span>06:00:00</span>"
                         "<span>06:07:30</span><span class=r>0.0</span><span class=r>0</span><span class=r>"
                         "<span class='hi'>185</span></span><span class=r>–</span><span class=r>93.4 %</span>"
                         "<span class=r>100.0 %</span><span class=r>100.0 %</span><span class=r>12.3</span></summary>")
    assert a1.count("<tr><td>") == 3  # X (departure), Y and Z (arrivals)
    assert "<tr><td>Y<td>arr.<td>06:03:00<td>2.5<td>0<td>10<td>20<td>50.0<td>100.0<td>100.0<td>0.0<td>1.0" in a1
    assert "<tr><td>Z &amp; Co<td>arr.<td>06:07:30<td>0.0<td>0<td><span class='hi'>185</span><td>–<td>93.4" in a1
    b2 = html[html.index("<b>B2</b>"):html.index("<b>A1</b>")]  # departs first: listed first
    assert "<span>05:00:00</span><span>–</span>" + "<span class=r>–</span>" * 8 + "</summary>" in b2
    assert "E6 · 2 trains" in html


def _split(frame, groups: dict, col: str = "train_id"):
    return {g: frame[frame[col].map(groups) == g] for g in sorted(set(groups.values()))}


def test_a_line_in_sections_renders_as_the_whole_line():
    """The page put together from the shares of a line's sections (each with its trains' rows) is the page of the
    whole line's frames, byte for byte: split by direction (as sections are: trains that share no track), and
    split across a train's headways (a place and cause met in two sections, a leg in several)."""
    from planner.pages.robustness import render_shares
    from planner.pages.robustness_share import share

    s, tr, st, acts, ev = frames(n_trains=40, n_stations=8)
    whole = render("Sample Line", s, tr, st, acts, ev)
    ids = sorted(set(tr["train_id"]), key=lambda t: int(t[1:]))
    for groups in ({t: int(t[1:]) % 2 for t in ids}, {t: int(t[1:]) // 7 for t in ids}):
        trs, evs = _split(tr, groups), _split(ev, groups)
        acs = _split(acts, groups, "to_train")
        shares = [share(trs[g], st, acs[g], evs[g], s["days"]) for g in sorted(trs)]
        assert len(shares) > 1 and sum(len(x.dist) for x in shares) == 40
        assert render_shares("Sample Line", s, st, shares) == whole


def test_the_largest_rows_come_from_any_section():
    """Each "largest" table over the line takes its rows from whichever section has them: the section order does
    not matter, only the figures."""
    from planner.pages.robustness import render_shares
    from planner.pages.robustness_share import share

    s, tr, st, acts, ev = frames(n_trains=60, n_stations=6, seed=11)
    groups = {t: int(t[1:]) % 3 for t in set(tr["train_id"])}
    trs, evs, acs = _split(tr, groups), _split(ev, groups), _split(acts, groups, "to_train")
    shares = [share(trs[g], st, acs[g], evs[g], s["days"]) for g in sorted(trs)]
    one = render_shares("L", s, st, shares)
    assert render_shares("L", s, st, shares[::-1]).split("<h2 id='spread'>")[1] == one.split("<h2 id='spread'>")[1]
    assert one == render("L", s, tr, st, acts, ev)
