"""Real files as railways export them: each deviation of the wild, reproduced in a small file written here.

The fixtures are written for these tests (not copied from any export). Positions are
checked in closed form from absPos arithmetic: an element at ``pos`` on a track whose
trackBegin has absPos ``A`` is at chainage ``A + pos``.
"""
from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

import importsrc as src
from planner import load_line
from planner.errors import SourceError, SourceProblems
from planner.line.importers.railjson import import_railjson
from planner.line.importers.railml import import_railml

KMH = 1 / 3.6


def _track(tid, length, abs_begin=None, begin_conn="", end_conn="", elements="", ocs=""):
    ab = "" if abs_begin is None else f' absPos="{abs_begin}"'
    ae = "" if abs_begin is None else f' absPos="{abs_begin + length}"'
    return f"""
    <track id="{tid}">
      <trackTopology>
        <trackBegin id="b{tid}" pos="0"{ab}>{begin_conn or f'<openEnd id="ob{tid}"/>'}</trackBegin>
        <trackEnd id="e{tid}" pos="{length}"{ae}>{end_conn or f'<openEnd id="oe{tid}"/>'}</trackEnd>
      </trackTopology>
      <trackElements>{elements}</trackElements>
      <ocsElements>{ocs}</ocsElements>
    </track>"""


def _conn(cid, ref):
    return f'<connection id="{cid}" ref="{ref}"/>'


def _railml(tracks: str, refs: str, ocps: str = "", attrs: str = "") -> str:
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<railml xmlns="http://www.railml.org/schemas/2013" version="2.2">
 <infrastructure id="i">
  {attrs}
  <tracks>{tracks}</tracks>
  <trackGroups><line id="L">{refs}</line></trackGroups>
  <operationControlPoints>{ocps}</operationControlPoints>
 </infrastructure>
</railml>"""


STATIONS_BY_KM = """
[stations.S1]
position_m = 10100.0
[stations.S2]
position_m = 12900.0
"""

SPEED = '<speedChanges><speedChange id="v0" pos="0" dir="up" vMax="100"/></speedChanges>'


def _three(a_end="", b_begin=None, a_ocs="", b_ocs="", c_ocs="", absolute=True, refs=None):
    """Tracks A 0–1000 (absPos 10000–11000), B 0–500 (11000–11500), C 0–1500 (11500–13000), connected."""
    ab = (10000, 11000, 11500) if absolute else (None, None, None)
    tracks = (_track("A", 1000, ab[0], end_conn=a_end or _conn("cAB", "cBA"), elements=SPEED, ocs=a_ocs)
              + _track("B", 500, ab[1], begin_conn=b_begin or _conn("cBA", "cAB"), end_conn=_conn("cBC", "cCB"),
                       ocs=b_ocs)
              + _track("C", 1500, ab[2], begin_conn=_conn("cCB", "cBC"), ocs=c_ocs))
    refs = refs or '<trackRef ref="A"/><trackRef ref="B"/><trackRef ref="C"/>'
    return _railml(tracks, refs)


def _run(tmp_path: Path, text: str, extra: str = STATIONS_BY_KM, **kw):
    tmp_path.mkdir(parents=True, exist_ok=True)
    f = tmp_path / "wild.xml"
    f.write_text(text)
    x = tmp_path / "extra.toml"
    x.write_text(extra)
    r = tmp_path / "emu.json"
    r.write_text(json.dumps(src.rolling_stock()))
    out = tmp_path / "out"
    return import_railml(f, "L", [r], out, extra=x, **kw), out


def _col(out: Path, table: str, col: str) -> list:
    return pq.read_table(out / f"{table}.parquet").column(col).to_pylist()


def _notes(s) -> str:
    return "\n".join(s.notes + s.unused)


# --------------------------------------------------------------------------- railML deviations
def test_chainage_is_the_km_posts_of_absPos(tmp_path):
    s, out = _run(tmp_path, _three(b_ocs='<signals><signal id="S" pos="200" dir="up" type="main"/></signals>'))
    line = load_line(out)
    assert (line.start_m, line.end_m) == (10000.0, 13000.0)
    assert _col(out, "signals", "position_m") == [11000.0 + 200.0]
    assert _col(out, "stations", "position_m") == [10100.0, 12900.0]  # by km post, from --extra
    assert "chainage = the railway's km posts (absPos): 10000 … 13000 m" in _notes(s)


def test_trackref_id_is_taken_for_ref_with_a_note(tmp_path):
    refs = '<trackRef id="A"/><trackRef id="B"/><trackRef id="C"/>'
    s, out = _run(tmp_path, _three(refs=refs, b_ocs='<signals><signal id="S" pos="200" dir="up"/></signals>'))
    assert "3 <trackRef> of line 'L' name their track with @id instead of @ref" in _notes(s)
    assert _col(out, "signals", "position_m") == [11200.0]


def test_a_gap_in_the_sequence_is_joined_where_absPos_runs_on(tmp_path):
    text = _three(a_end=_conn("cAB", "cMISSING"), b_begin=_conn("cBA", "A"),
                  b_ocs='<balises><balise id="Q" pos="100" dir="down"/></balises>')
    s, out = _run(tmp_path, text)
    assert "track 'A''s trackEnd connects to cMISSING, not to the next track of line 'L', 'B'; joined because " \
           "absPos runs on (11000 m = 11000 m)" in _notes(s)
    assert _col(out, "beacons", "position_m") == [11000.0 + 100.0]


def test_a_missing_track_is_found_through_its_connections(tmp_path):
    """No absPos: B is not a trackRef of the line, but A's end and C's begin connect through it."""
    text = _three(absolute=False, refs='<trackRef ref="A"/><trackRef ref="C"/>',
                  c_ocs='<signals><signal id="S" pos="100" dir="up"/></signals>')
    s, out = _run(tmp_path, text, extra=STATIONS_BY_KM.replace("10100.0", "100.0").replace("12900.0", "2900.0"))
    assert "track 'B' (not a trackRef of line 'L') joins 'A' and 'C' through their connections: inserted" in _notes(s)
    assert _col(out, "signals", "position_m") == [1000.0 + 500.0 + 100.0]
    assert "chainage from 0 at the first trackBegin" in _notes(s)


def test_pos_past_the_track_end_is_placed_by_absPos(tmp_path):
    a_ocs = ('<signals><signal id="S" pos="1200" absPos="11200" dir="up"/></signals>'
             '<balises><balise id="Q" pos="1600" absPos="11600" dir="down"/></balises>')
    c_ocs = '<balises><balise id="OFF" pos="1700" absPos="13200" dir="down"/></balises>'
    s, out = _run(tmp_path, _three(a_ocs=a_ocs, c_ocs=c_ocs))
    assert _col(out, "signals", "position_m") == [11200.0]  # on B, by its km post
    assert _col(out, "beacons", "position_m") == [11600.0]  # on C
    text = _notes(s)
    assert "2 elements with pos past their track's end placed by their absPos (km post): S (A pos 1200 → absPos " \
           "11200), Q (A pos 1600 → absPos 11600)" in text
    assert "1 elements whose pos and absPos both lie beyond the line's ends" in text and "OFF (absPos 13200)" in text


def test_every_problem_of_a_file_is_reported_at_once(tmp_path):
    b_ocs = ('<signals><signal id="S1" pos="2.8km" dir="up"/><signal id="S2" pos="100" dir="sideways"/></signals>'
             '<balises><balise id="Q" pos="900" dir="up"/></balises>')  # past B's end, no absPos
    with pytest.raises(SourceProblems) as e:
        _run(tmp_path, _three(absolute=False, b_ocs=b_ocs))
    got = e.value.problems
    assert len(got) == 3, got
    assert "<signal id='S1'> @pos: '2.8km' is not a number" in got[0]
    assert "<signal id='S2'> @dir: 'sideways'" in got[1]
    assert "<balise id='Q'> @pos: 900.0 is outside track 'B'" in got[2]
    assert "3 problems" in str(e.value) and not (tmp_path / "out").exists()


def test_a_file_without_ocps_says_how_to_add_stations(tmp_path):
    with pytest.raises(SourceError, match=r"wild.xml: this file has no OCPs \(operationControlPoints\); add stations "
                                          r"with \[stations.X\] position_m in --extra \(chainage 10000 … 13000 m"):
        _run(tmp_path, _three(), extra="")


def test_an_unknown_station_gets_did_you_mean_and_the_list(tmp_path):
    text = _three().replace("<operationControlPoints>", '<operationControlPoints><ocp id="NORTH"/><ocp id="SOUTH"/>')
    text = text.replace('<trackEnd id="eA"', '<crossSections><crossSection id="x1" pos="50" ocpRef="NORTH"/>'
                        '</crossSections><trackEnd id="eA"', 1)
    text = text.replace('<trackEnd id="eC"', '<crossSections><crossSection id="x2" pos="50" ocpRef="SOUTH"/>'
                        '</crossSections><trackEnd id="eC"', 1)
    with pytest.raises(SourceError, match=r"\[stations.NROTH\]: no station 'NROTH' on the imported path; did you "
                                          r"mean NORTH\?; stations are NORTH, SOUTH"):
        _run(tmp_path, text, extra="[stations.NROTH]\nplatform_length_m = 150.0\n")


ATTRS = """<infraAttrGroups>
    <infraAttributes id="p1"><speeds><speed trainCategory="pass" vMax="90"/><speed trainCategory="freight"
      vMax="60"/></speeds></infraAttributes>
  </infraAttrGroups>"""


def test_train_category_speeds_become_per_train_type_limits(tmp_path):
    text = _three().replace('vMax="100"/>', 'vMax="100" profileRef="p1"/>').replace("<tracks>", ATTRS + "<tracks>")
    s, out = _run(tmp_path, text, categories=["EMU=freight"])
    rows = sorted(zip(_col(out, "speed_limits", "start_m"), _col(out, "speed_limits", "end_m"),
                      _col(out, "speed_limits", "limit_kmh"), _col(out, "speed_limits", "train_type"),
                      _col(out, "speed_limits", "direction")), key=str)
    assert rows == [(10000.0, 13000.0, 100.0, None, "both"), (10000.0, 13000.0, 60.0, "EMU", "both")]
    assert "speed limits of train category pass (no train type maps to them" in _notes(s)
    line = load_line(out)
    assert min(x.limit_ms for x in line.limits_for("up", "EMU")) == pytest.approx(60 * KMH)
    with pytest.raises(SourceError, match="no train category 'frieght'; did you mean freight"):
        _run(tmp_path, text, categories=["EMU=frieght"])


def test_speed_changes_apply_per_direction_and_one_direction_files_to_both(tmp_path):
    both = SPEED.replace("</speedChanges>", '<speedChange id="v1" pos="1000" dir="down" vMax="70"/></speedChanges>')
    s, out = _run(tmp_path, _three().replace(SPEED, both))
    rows = sorted(zip(_col(out, "speed_limits", "start_m"), _col(out, "speed_limits", "end_m"),
                      _col(out, "speed_limits", "limit_kmh"), _col(out, "speed_limits", "direction")))
    # dir up (planner down) from A pos 0 to the line's end; dir down (planner up) from A pos 1000 to the start
    assert rows == [(10000.0, 11000.0, 70.0, "up"), (10000.0, 13000.0, 100.0, "down")]
    assert "every speedChange is for" not in _notes(s)
    s, out = _run(tmp_path / "one", _three())
    assert _col(out, "speed_limits", "direction") == ["both"]
    assert "every speedChange is for railML dir='up' (planner direction down); none for the other direction: " \
           "the limits are taken for both directions" in _notes(s)


# --------------------------------------------------------------------------- railjson and OSRD rolling stock
def _rj(tmp_path, infra=None, rs=None, extra="", path=("W", "M", "E"), **kw):
    i, r, x = src.write_railjson(tmp_path, infra, rs)
    x.write_text(extra)
    return import_railjson(i, list(path), [r], tmp_path / "out", extra=x, **kw), tmp_path / "out"


def test_speed_limit_by_tag_becomes_a_per_train_type_limit(tmp_path):
    s, out = _rj(tmp_path, categories=["EMU=freight"])
    rows = [r for r in pq.read_table(out / "speed_limits.parquet").to_pylist() if r["train_type"] == "EMU"]
    assert [(r["start_m"], r["end_m"], r["limit_kmh"]) for r in rows] == [(1200.0, 1600.0, 60.0)]
    assert "per-train-type speed limits from speed_limit_by_tag: EMU = freight" in _notes(s)
    s, _ = _rj(tmp_path / "unmapped")
    assert "speed limits of speed tag freight (no train type maps to them" in _notes(s)


def test_an_infra_without_operational_points_says_so_and_takes_track_sections(tmp_path):
    infra = src.edited(src.railjson_infra, lambda d: d.update(operational_points=[]))
    with pytest.raises(SourceError, match="this file has no operational points; name track sections in --path"):
        _rj(tmp_path, infra)
    s, out = _rj(tmp_path / "ok", infra, path=("T1", "T3"), extra=STATIONS_BY_KM.replace("10100.0", "500.0")
                 .replace("12900.0", "6200.0"))
    assert _col(out, "stations", "position_m") == [500.0, 6200.0]
    assert load_line(out).end_m == 6500.0  # T1 + T2 + T3 whole


def test_an_unknown_operational_point_gets_did_you_mean_and_the_ids(tmp_path):
    with pytest.raises(SourceError, match=r"unknown operational point 'Mx'; did you mean M\? \(operational_points "
                                          r"ids: B, E, M, W; or a track section id\)"):
        _rj(tmp_path, path=("W", "Mx"))


def test_two_paths_of_one_file_get_different_line_ids(tmp_path):
    a, _ = _rj(tmp_path / "a", path=("W", "M"))
    b, _ = _rj(tmp_path / "b", path=("M", "E"))
    assert (a.line_id, b.line_id) == ("infra_W_M", "infra_M_E")


def test_a_short_effort_curve_is_extended_at_constant_power(tmp_path):
    """OSRD's fast test stocks stop their curve below max_speed; the last point's power P = F·v holds."""
    def short(d):
        d["effort_curves"]["modes"]["1500V"]["default_curve"].update(speeds=[0.0, 10.0, 20.0],
                                                                     max_efforts=[200000.0, 200000.0, 60000.0])
        d.update(gamma={"type": "MAX", "value": 1.0}, energy_sources=[{"energy_source_type": "Battery"}])
        del d["const_gamma"]
    s, out = _rj(tmp_path, rs=src.edited(src.rolling_stock, short))
    speeds, efforts = _col(out, "traction", "speed_kmh"), _col(out, "traction", "effort_kN")
    vmax = 110 * KMH
    assert speeds[-1] == pytest.approx(110.0) and efforts[-1] == pytest.approx(60.0 * 20.0 / vmax, rel=1e-9)
    assert len(speeds) == 3 + 11  # 20 → 30.56 m/s in steps of at most 1 m/s
    for v, f in zip(speeds[2:], efforts[2:]):
        assert f * v / 3.6 == pytest.approx(60.0 * 20.0, rel=1e-9)  # F·v = P of the last point [kW]
    text = _notes(s)
    assert "effort curve ends at 20 m/s, below max_speed 30.5556 m/s: extended at the constant power" in text
    for field in ("startup_time = 5.0", "startup_acceleration = 0.05", "energy_sources", "gamma.type = 'MAX'"):
        assert field in text, field


def test_cli_lists_every_problem_on_its_own_line(tmp_path, monkeypatch, capsys):
    import sys

    from planner.cli import main

    b_ocs = '<signals><signal id="S1" pos="2.8km" dir="up"/><signal id="S2" pos="100" dir="sideways"/></signals>'
    f = tmp_path / "wild.xml"
    f.write_text(_three(b_ocs=b_ocs))
    r = tmp_path / "emu.json"
    r.write_text(json.dumps(src.rolling_stock()))
    monkeypatch.setattr(sys, "argv", ["planner", "import", "railml", str(f), "--line", "L", "--rolling-stock", str(r),
                                      "--out", str(tmp_path / "x")])
    with pytest.raises(SystemExit) as e:
        main()
    err = capsys.readouterr().err.splitlines()
    assert e.value.code == 1 and len(err) == 4, err  # two problems, the missing stations, then the error
    assert err[0].startswith("  - wild.xml: <signal id='S1'> @pos") and "'sideways'" in err[1]
    assert "this file has no OCPs" in err[2]
    assert err[3] == "error: wild.xml: 3 problems in the source (each listed above); fix them and import again"


def test_a_profile_ref_to_something_else_is_named_not_refused(tmp_path):
    text = _three().replace('vMax="100"/>', 'vMax="100" profileRef="sp9"/>')
    s, out = _run(tmp_path, text)
    assert _col(out, "speed_limits", "limit_kmh") == [100.0]
    assert "speed profiles sp9 named by speedChange profileRef (only infraAttrGroups" in _notes(s)
