"""Every page says of every leg what the ``margins`` dataset says, on two restricted days.

Day 1 is the sample job's own day (2026-11-30: the sample feed's restrictions, legs that lose their margin,
legs short on a bad day); day 2 is 2026-12-01 with a restriction of our own that leaves the up trains no
stopping pattern at Midorigaoka (the case where the pages once disagreed: the overview counted no such leg, the
margin report gave them a bad-day figure, the restrictions page said they still made it).

Read back from the published files, per leg (train type, direction, origin, destination, the restrictions its
trains run with): the margin report row's badges are the dataset row's flags; the restrictions page row's
verdict follows from the same row's flags; the overview's cards count the dataset's flags (rows of it, as the
margin report does; a leg without a stopping pattern once, as the manifest's ``no_stop`` does).
"""
from __future__ import annotations

import html
import re
import shutil
from pathlib import Path

import pyarrow.dataset as ds
import pytest
from typer.testing import CliRunner

from planner.cli import app

ROOT = Path(__file__).resolve().parents[1]
OURS = ("restriction_id,start_m,end_m,limit_kmh,direction,train_type,valid_from,valid_until,reason,has_beacon\n"
        "OURS-1,9000.0,9300.0,40.0,up,,2026-12-01T09:00,2026-12-01T15:00,test,false\n")
FLAGS = ("unassessed", "impossible", "short_bad_day", "unreachable", "inaccurate", "tight")  # the shown flags


@pytest.fixture(scope="module", params=["2026-11-30", "2026-12-01"])
def night(request, tmp_path_factory):
    day = request.param
    tmp = tmp_path_factory.mktemp(f"day{day}")
    shutil.copytree(ROOT / "feeds" / "sample", tmp / "feed")
    if day == "2026-12-01":
        (tmp / "r.csv").write_text(OURS)
        r = CliRunner().invoke(app, ["restrictions", "import", str(tmp / "r.csv"), "--line",
                                     str(ROOT / "lines" / "sample"), "--feed", str(tmp / "feed"),
                                     "--time-zone", "Asia/Tokyo"])
        assert r.exit_code == 0, r.output
    job = (ROOT / "jobs" / "nightly.toml").read_text()
    job = job.replace('lines = ["lines/sample"]', f'lines = ["{ROOT / "lines" / "sample"}"]')
    job = job.replace('output_root = "outputs"', f'output_root = "{tmp / "out"}"')
    job = job.replace('feeds = ["feeds/sample"]', f'feeds = ["{tmp / "feed"}"]')
    job = job.replace('day = "2026-11-30"', f'day = "{day}"').replace('run_date = ""', f'run_date = "{day}"')
    (tmp / "job.toml").write_text(job)
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    result = run_job(load_job(tmp / "job.toml"), show_progress=False)
    margins = ds.dataset(result.run_dir / "margins", partitioning="hive").to_table().to_pandas()
    return result.run_dir, margins


def _key(tt, d, o, de, restrictions) -> tuple:
    return str(tt), str(d), str(o), str(de), tuple(sorted(map(str, restrictions)))


def _flags(r) -> frozenset:
    return frozenset(f for f in FLAGS if r[f] is True or r[f] == True)  # noqa: E712 (numpy/pandas booleans)


def _cells(tr: str) -> list[str]:
    return re.findall(r"<td[^>]*>(.*?)</td>", tr, flags=re.S)


def _text(cell: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", cell)).strip()


def test_the_days_are_restricted_and_have_flagged_legs(night):
    _, m = night
    assert m["restrictions"].map(len).gt(0).any()
    assert m[list(FLAGS)].fillna(False).astype(bool).any(axis=None)


def test_the_margin_report_shows_each_legs_flags(night):
    run, m = night
    want = {}
    for r in m.to_dict("records"):
        k = _key(r["train_type"], r["direction"], r["origin"], r["destination"], r["restrictions"])
        assert k not in want, f"two dataset rows for {k}"
        want[k] = _flags(r)
    page = (run / "report" / "sample_margins.html").read_text()
    got = {}
    for tr in re.findall(r"<tr(?: class='\w+')? title='[^']*'>(.*?)</tr>", page, flags=re.S):
        c = _cells(tr)
        if len(c) < 4 or "class='nw'" not in c[3]:
            continue
        o, de = _text(re.search(r"<span class='nw'>(.*?)</span>", c[3]).group(1)).split(" → ")
        w = re.search(r"\(with (.*?)\)", _text(c[3]))
        badges = frozenset(re.findall(r"class='badge b-(\w+)'", c[0])) - {"short"}  # 'supplement short' is no flag
        got[_key(_text(c[2]), _text(c[1]), o, de, w.group(1).split(", ") if w else [])] = badges
    assert got == want


def test_the_restrictions_page_verdict_follows_the_legs_flags(night):
    run, m = night
    by = {}
    for r in m.to_dict("records"):
        by.setdefault((r["train_type"], r["origin"], r["destination"], tuple(sorted(r["restrictions"]))), []).append(r)
    page = (run / "report" / "sample_restrictions.html").read_text()
    table = page.split("id='trains'")[1].split("</table>")[0]
    rows = [_cells(tr) for tr in re.findall(r"<tr>(.*?)</tr>", table, flags=re.S)]
    rows = [c for c in rows if len(c) == 13]
    assert rows
    seen = set()
    for c in rows:
        tt, leg = _text(c[0]).split(" ", 1)
        o, de = leg.split("→")
        restr = () if _text(c[1]) == "none" else tuple(sorted(_text(c[1]).split(", ")))
        verdict = _text(c[11])
        rs = by.get((tt, o, de, restr))
        assert rs, f"restrictions page row {tt} {o}→{de} {restr} has no margins row"
        (r,) = rs
        f = _flags(r)
        seen.add(verdict)
        if verdict == "no stopping pattern":
            assert r["unassessed_cause"] == "no_stop"
        else:
            assert r["unassessed_cause"] != "no_stop", (tt, o, de, verdict)
        if verdict == "still makes it":
            assert not f & {"unassessed", "impossible", "short_bad_day", "tight"}, (tt, o, de, f)
            assert r["margin_s"] >= 0
        if verdict in ("loses its margin", "had none"):
            assert r["margin_s"] < 0 and "impossible" in f, (tt, o, de, f)
        if verdict == "short on a bad day":
            assert "short_bad_day" in f
        if verdict == "tight on a bad day":
            assert f == {"tight"} or f == {"tight", "inaccurate"}
        if verdict == "unassessed":
            assert "unassessed" in f
    assert len(seen) >= 2  # the days give the page more than one thing to say


def test_the_overview_counts_the_datasets_flags(night):
    run, m = night
    page = (run / "index.html").read_text()
    cards = {_text(label).split(":")[0]: int(n) for n, label in
             re.findall(r"<div class='n'>(\d+)</div><div class='l'>(.*?)</div>", page)}
    for f, words in (("unassessed", "legs unassessed"), ("impossible", "legs impossible"),
                     ("short_bad_day", "legs short on a bad day"), ("unreachable", "legs unreachable"),
                     ("inaccurate", "legs inaccurate"), ("tight", "legs tight")):
        assert cards[words] == int(m[f].fillna(False).astype(bool).sum()), f
    # no stopping pattern is a verdict on the leg, however many restriction rows it has (each counted above)
    no_stop = m[m["unassessed_cause"] == "no_stop"]
    legs = {(r.train_type, r.direction, r.origin, r.destination) for r in no_stop.itertuples()}
    assert cards["legs where no stopping pattern stops the train (each leg once, with or without the day's "
                 "restrictions; the notes say where)"] == len(legs)
    assert len(legs) == (3 if str(m["run_date"].iloc[0]) == "2026-12-01" else 0)
