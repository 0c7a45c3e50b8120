"""railML as a CAD tool exports a station area: a fixture of our own in the shape of a RailCOMPLETE export.

The shape (seen in a RailCOMPLETE 2019 railML 2.2 export of a station area): the ``<line>`` lists every track
of the drawing; each main track runs from an open end to an open end, the crossovers join the mains by
switches along them, so no track's end connects to another track's begin; speeds are
``infraAttributes/speeds/speed[@etcsTrainCategory]`` profiles, one speed for every category, referenced by
speedChanges whose own ``vMax`` is a placeholder (350 km/h). The file here is written for this test with
figures of our own.
"""
from __future__ import annotations

import json

import pyarrow.parquet as pq
import pytest

import importsrc as src
from planner import load_line
from planner.errors import SourceProblems
from planner.line.importers.railml import import_railml

_SPEEDS = """
    <infraAttrGroups>
      <infraAttributes id="p90"><speeds>
        <speed etcsTrainCategory="0" vMax="90"/><speed etcsTrainCategory="1" vMax="90"/>
      </speeds></infraAttributes>
      <infraAttributes id="p60"><speeds>
        <speed etcsTrainCategory="0" vMax="60"/><speed etcsTrainCategory="1" vMax="60"/>
      </speeds></infraAttributes>
    </infraAttrGroups>"""


def _main(tid: str, length: int, switches: str, speeds: str = "") -> str:
    return f"""
      <track id="{tid}" type="mainTrack">
        <trackTopology>
          <trackBegin id="b{tid}" pos="0" absPos="20000"><openEnd id="o{tid}1"/></trackBegin>
          <trackEnd id="e{tid}" pos="{length}" absPos="{20000 + length}"><openEnd id="o{tid}2"/></trackEnd>
          <connections>{switches}</connections>
        </trackTopology>
        <trackElements><speedChanges>{speeds}</speedChanges></trackElements>
        <ocsElements><signals>
          <signal id="s{tid}u" pos="50" absPos="20050" dir="up" type="main"/>
          <signal id="s{tid}d" pos="{length - 50}" absPos="{20000 + length - 50}" dir="down" type="main"/>
        </signals></ocsElements>
      </track>"""


def station_area(switched: bool = True) -> str:
    """Mains IN (1200 m) and OUT (1250 m), both from km 20.000, and a 310 m crossover X from a switch on OUT at
    300 m to one on IN at 600 m; the line lists X, IN, OUT in no running order. ``switched=False``: the same
    tracks without the switches (a listing of tracks that do not join at all)."""
    sw_out = '<switch id="swO" pos="300" absPos="20300"><connection id="cO" ref="cX1" orientation="outgoing"/></switch>'
    sw_in = '<switch id="swI" pos="600" absPos="20600"><connection id="cI" ref="cX2" orientation="incoming"/></switch>'
    out_speeds = ('<speedChange id="v1" pos="0" absPos="20000" dir="up" profileRef="p90" vMax="350"/>'
                  '<speedChange id="v2" pos="800" absPos="20800" dir="up" profileRef="p60" vMax="350"/>'
                  '<speedChange id="v3" pos="1250" absPos="21250" dir="down" profileRef="p60" vMax="350"/>'
                  '<speedChange id="v4" pos="800" absPos="20800" dir="down" profileRef="p90" vMax="350"/>')
    x_begin = '<connection id="cX1" ref="cO"/>' if switched else '<openEnd id="oX1"/>'
    x_end = '<connection id="cX2" ref="cI"/>' if switched else '<openEnd id="oX2"/>'
    return f"""<?xml version="1.0" encoding="utf-8"?>
<railml version="2.2" xmlns="http://www.railml.org/schemas/2013">
  <infrastructure id="inf">{_SPEEDS}
    <tracks>
      <track id="X" type="mainTrack">
        <trackTopology>
          <trackBegin id="bX" pos="0" absPos="20300">{x_begin}</trackBegin>
          <trackEnd id="eX" pos="310" absPos="20610">{x_end}</trackEnd>
        </trackTopology>
      </track>{_main("IN", 1200, sw_in if switched else "")}{_main("OUT", 1250, sw_out if switched else "", out_speeds)}
    </tracks>
    <trackGroups><line id="area"><trackRef ref="X"/><trackRef ref="IN"/><trackRef ref="OUT"/></line></trackGroups>
  </infrastructure>
</railml>
"""


def _write(tmp_path, text: str):
    tmp_path.mkdir(parents=True, exist_ok=True)
    f, r, x = tmp_path / "area.railml", tmp_path / "emu.json", tmp_path / "extra.toml"
    f.write_text(text)
    r.write_text(json.dumps(src.rolling_stock(), indent=1))
    x.write_text("[stations.P]\nposition_m = 20200.0\n\n[stations.Q]\nposition_m = 21100.0\n")
    return f, r, x


def test_a_cad_station_area_whose_mains_join_only_by_switches_takes_the_longest_switched_main(tmp_path):
    """No track's end connects to another's begin, so the through route of one track is the line: the longest
    track that switches join to the group (OUT, 1250 m, over IN, 1200 m, and the crossover X). Refused before
    with one 'is not connected to the next track' per pair of the listing."""
    f, r, x = _write(tmp_path / "src", station_area())
    s = import_railml(f, "area", [r], tmp_path / "line", extra=x)
    line = load_line(tmp_path / "line")
    assert (line.start_m, line.end_m) == (20000.0, 21250.0)  # OUT's km posts: the absPos of its two ends
    assert any("its through route OUT is the line, the other tracks (X, IN) the network around it" in n
               for n in s.notes)
    assert any("chainage = the railway's km posts" in n for n in s.notes)


def test_a_speed_profile_with_one_speed_for_every_etcs_category_is_the_limit(tmp_path):
    """The speedChanges' vMax 350 is a placeholder; the speed is the profile's, the same for every ETCS category
    the profile names: it is every train's limit (before: 'speed @trainCategory: missing', and without the
    profile the line would have run at 350 km/h)."""
    f, r, x = _write(tmp_path / "src", station_area())
    s = import_railml(f, "area", [r], tmp_path / "line", extra=x)
    lim = pq.read_table(tmp_path / "line" / "speed_limits.parquet").to_pandas()
    general = lim[lim["train_type"].isna()]
    got = sorted((r.direction, r.start_m, r.end_m, r.limit_kmh) for r in general.itertuples())
    # up (railML dir=up = planner down): 90 from km 20.0, 60 from km 20.8; down (planner up): 60 from the end, 90
    # from km 20.8 back to the start
    assert got == [("down", 20000.0, 20800.0, 90.0), ("down", 20800.0, 21250.0, 60.0),
                   ("up", 20000.0, 20800.0, 90.0), ("up", 20800.0, 21250.0, 60.0)]
    assert any("4 speedChanges whose profile gives every train category it names one speed" in n for n in s.notes)


def test_tracks_listed_together_that_neither_chain_nor_switch_together_are_still_refused(tmp_path):
    f, r, x = _write(tmp_path / "src", station_area(switched=False))
    with pytest.raises(SourceProblems) as e:
        import_railml(f, "area", [r], tmp_path / "line", extra=x)
    assert len(e.value.problems) == 2  # X → IN and IN → OUT, one line each
    assert all("is not connected to the next track of line 'area'" in p for p in e.value.problems)
