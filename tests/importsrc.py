"""Small source files for the importer tests, written here (not copied from anywhere).

One line in three sources: an OSRD railjson infrastructure, a railML 2.x file and,
by hand, the line database both must import to. Geometry (chainage from the
western end, direction down = west → east):

====================  ======================================================
0 … 3000 m            track T1 (railjson START_TO_STOP / railML tr1)
3000 … 5000 m         track T2; railjson runs it STOP_TO_START (its END meets T1's
                      END through a point switch), railML orients it west → east
5000 … 6500 m         track T3
stations              W 500 m, M 4000 m, E 6200 m (platforms 200 m by default)
gradients [‰]         0–1000 +5, 1500–2500 −8, 3200–4800 −6, 5000–5700 +3
curves [m]            1200–1600 R600, 5300–5800 R800
speed limits [km/h]   100 everywhere; 80 over 1200–1600; 60 over 3100–3500 (up only)
signals               SIG1 2800 down, SIG2 4700 down, SIG3 5100 up
detector              D1 6000 (an ATS-P beacon stands there, given in the TOML)
====================  ======================================================

railjson T2 is 2000 m long and run backwards: offset x on T2 is chainage 5000 − x,
and its slope +6 ‰ over offsets 200–1800 falls −6 ‰ over chainage 3200–4800; its
60 km/h section START_TO_STOP over offsets 1500–1900 applies to trains running
towards decreasing offsets' opposite, i.e. towards decreasing chainage: ``up``.
"""
from __future__ import annotations

import copy
import json
from pathlib import Path

import pandas as pd

from planner.line.schema import SCHEMA_VERSION

KMH = 1 / 3.6


def _ts(tid, length, slopes=(), curves=()):
    return {"id": tid, "length": length,
            "slopes": [{"begin": b, "end": e, "gradient": g} for b, e, g in slopes],
            "curves": [{"begin": b, "end": e, "radius": r} for b, e, r in curves],
            "geo": {"type": "LineString", "coordinates": [[0, 0], [1, 1]]}}


def _range(track, b, e, dirs="BOTH"):
    return {"track": track, "begin": b, "end": e, "applicable_directions": dirs}


def railjson_infra() -> dict:
    return {
        "version": "3.4.12",
        "track_sections": [
            _ts("T1", 3000.0, [(0.0, 1000.0, 5.0), (1500.0, 2500.0, -8.0)], [(1200.0, 1600.0, -600.0)]),
            _ts("T2", 2000.0, [(200.0, 1800.0, 6.0)]),
            _ts("T3", 1500.0, [(0.0, 700.0, 3.0)], [(300.0, 800.0, 800.0)]),
            _ts("TB", 800.0, [(0.0, 800.0, 30.0)]),
        ],
        "switches": [
            {"id": "SW1", "switch_type": "point_switch", "group_change_delay": 4.0,
             "ports": {"A": {"track": "T1", "endpoint": "END"}, "B1": {"track": "T2", "endpoint": "END"},
                       "B2": {"track": "TB", "endpoint": "BEGIN"}}},
            {"id": "L1", "switch_type": "link", "group_change_delay": 0.0,
             "ports": {"A": {"track": "T2", "endpoint": "BEGIN"}, "B": {"track": "T3", "endpoint": "BEGIN"}}},
        ],
        "speed_sections": [
            {"id": "V100", "speed_limit": 100 * KMH, "speed_limit_by_tag": {},
             "track_ranges": [_range("T1", 0.0, 3000.0), _range("T2", 0.0, 2000.0), _range("T3", 0.0, 1500.0)]},
            {"id": "V80", "speed_limit": 80 * KMH, "speed_limit_by_tag": {"freight": 60 * KMH},
             "track_ranges": [_range("T1", 1200.0, 1600.0)]},
            {"id": "V60", "speed_limit": 60 * KMH, "speed_limit_by_tag": {},
             "track_ranges": [_range("T2", 1500.0, 1900.0, "START_TO_STOP")]},
            {"id": "VB", "speed_limit": 30 * KMH, "speed_limit_by_tag": {},
             "track_ranges": [_range("TB", 0.0, 800.0)]},
        ],
        "signals": [
            {"id": "SIG1", "track": "T1", "position": 2800.0, "direction": "START_TO_STOP", "sight_distance": 400},
            {"id": "SIG2", "track": "T2", "position": 300.0, "direction": "STOP_TO_START", "sight_distance": 400},
            {"id": "SIG3", "track": "T3", "position": 100.0, "direction": "STOP_TO_START", "sight_distance": 400},
            {"id": "SIGB", "track": "TB", "position": 100.0, "direction": "START_TO_STOP", "sight_distance": 400},
        ],
        "detectors": [{"id": "D1", "track": "T3", "position": 1000.0}],
        "buffer_stops": [],
        "operational_points": [
            {"id": "W", "parts": [{"track": "T1", "position": 500.0}],
             "extensions": {"identifier": {"name": "West", "uic": 1}}},
            {"id": "M", "parts": [{"track": "T2", "position": 1000.0}],
             "extensions": {"identifier": {"name": "Middle", "uic": 2}}},
            {"id": "E", "parts": [{"track": "T3", "position": 1200.0}],
             "extensions": {"identifier": {"name": "East", "uic": 3}}},
            {"id": "B", "parts": [{"track": "TB", "position": 400.0}]},
        ],
        "routes": [], "electrifications": [], "neutral_sections": [], "level_crossings": [],
        "extended_switch_types": [],
    }


def rolling_stock() -> dict:
    """An OSRD rolling stock in SI units (m, kg, m/s, N)."""
    return {
        "railjson_version": "3.2",
        "name": "EMU",
        "length": 120.0,
        "mass": 250000.0,
        "max_speed": 110 * KMH,
        "inertia_coefficient": 1.08,
        "comfort_acceleration": 0.75,
        "startup_time": 5.0,
        "startup_acceleration": 0.05,
        "const_gamma": 1.0,
        "rolling_resistance": {"type": "davis", "A": 3600.0, "B": 36.0, "C": 5.184},
        "loading_gauge": "G1",
        "effort_curves": {"default_mode": "1500V", "modes": {"1500V": {
            "is_electric": True, "curves": [],
            "default_curve": {"speeds": [0.0, 40 * KMH, 120 * KMH], "max_efforts": [200000.0, 200000.0, 60000.0]},
        }}},
    }


EXTRA_TOML = """
[line]
name = "Import test line"

[stations.E]
platform_length_m = 160.0

[rolling_stock.EMU]
jerk_limit_kmh_s2 = 2.5
full_load_mass_t = 60.0

[[beacons]]
beacon_id = "BC1"
at = "D1"
direction = "up"
kind = "signal"
telegram = "SIG3:G"
evaluation_point = true

[[timetable]]
train_id = "1"
train_type = "EMU"
direction = "down"
seq = 0
station_id = "W"
departure_s = 21600.0
stops = true

[[timetable]]
train_id = "1"
train_type = "EMU"
direction = "down"
seq = 1
station_id = "M"
arrival_s = 21900.0
departure_s = 21930.0
stops = true

[[timetable]]
train_id = "1"
train_type = "EMU"
direction = "down"
seq = 2
station_id = "E"
arrival_s = 22200.0
stops = true
"""


def expected_tables(line_id: str) -> dict[str, pd.DataFrame]:
    """The line database both sources describe, written by hand in railway units."""
    N = None
    return {
        "line": pd.DataFrame([dict(line_id=line_id, name="Import test line", start_m=0.0, end_m=6500.0,
                                   max_speed_kmh=None, schema_version=SCHEMA_VERSION)]),
        "stations": pd.DataFrame(
            [("W", "West", 500.0, 600.0, 400.0, 200.0), ("M", "Middle", 4000.0, 4100.0, 3900.0, 200.0),
             ("E", "East", 6200.0, 6280.0, 6120.0, 160.0)],
            columns=["station_id", "name", "position_m", "stop_down_m", "stop_up_m", "platform_length_m"]),
        "gradients": pd.DataFrame([(0.0, 1000.0, 5.0), (1500.0, 2500.0, -8.0), (3200.0, 4800.0, -6.0),
                                   (5000.0, 5700.0, 3.0)], columns=["start_m", "end_m", "gradient_permil"]),
        "curves": pd.DataFrame([(1200.0, 1600.0, 600.0), (5300.0, 5800.0, 800.0)],
                               columns=["start_m", "end_m", "radius_m"]),
        "speed_limits": pd.DataFrame(
            [(0.0, 3000.0, 100.0, "both", N, "civil", False), (1200.0, 1600.0, 80.0, "both", N, "civil", False),
             (3000.0, 5000.0, 100.0, "both", N, "civil", False), (3100.0, 3500.0, 60.0, "up", N, "civil", False),
             (5000.0, 6500.0, 100.0, "both", N, "civil", False)],
            columns=["start_m", "end_m", "limit_kmh", "direction", "train_type", "kind", "has_beacon"]),
        "beacons": pd.DataFrame([("BC1", 6000.0, "up", "signal", "SIG3:G", True)],
                                columns=["beacon_id", "position_m", "direction", "kind", "telegram",
                                         "evaluation_point"]),
        "signals": pd.DataFrame([("SIG1", 2800.0, "down"), ("SIG2", 4700.0, "down"), ("SIG3", 5100.0, "up")],
                                columns=["signal_id", "position_m", "direction"]),
        "rolling_stock": pd.DataFrame([dict(
            train_type="EMU", length_m=120.0, empty_mass_t=250.0, full_load_mass_t=60.0,
            rotating_mass_factor=0.08, max_speed_kmh=110.0, max_accel_kmh_s=2.7, davis_a_kN=3.6,
            davis_b_kN_per_kmh=0.01, davis_c_kN_per_kmh2=0.0004, service_brake_kmh_s=3.6, stop_brake_kmh_s=3.6,
            atsp_pattern_kmh_s=3.6, brake_comfort_kmh_s=3.3, jerk_limit_kmh_s2=2.5, speed_margin_kmh=0.0,
            cruise="constant", coast_band_kmh=0.0)]),
        "traction": pd.DataFrame([("EMU", 0.0, 200.0), ("EMU", 40.0, 200.0), ("EMU", 120.0, 60.0)],
                                 columns=["train_type", "speed_kmh", "effort_kN"]),
        "timetable": pd.DataFrame(
            [("1", "EMU", "down", 0, "W", N, 21600.0, True), ("1", "EMU", "down", 1, "M", 21900.0, 21930.0, True),
             ("1", "EMU", "down", 2, "E", 22200.0, N, True)],
            columns=["train_id", "train_type", "direction", "seq", "station_id", "arrival_s", "departure_s",
                     "stops"]),
    }


def write_railjson(folder: Path, infra: dict | None = None, rs: dict | None = None) -> tuple[Path, Path, Path]:
    """Write infra.json, emu.json and extra.toml into ``folder``; return their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    i, r, x = folder / "infra.json", folder / "emu.json", folder / "extra.toml"
    i.write_text(json.dumps(railjson_infra() if infra is None else infra, indent=1))
    r.write_text(json.dumps(rolling_stock() if rs is None else rs, indent=1))
    x.write_text(EXTRA_TOML)
    return i, r, x


def edited(make, edit) -> dict:
    d = copy.deepcopy(make())
    edit(d)
    return d


RAILML_NS = "http://www.railml.org/schemas/2016"


def railml_text(tracks: str | None = None, lines: str | None = None, ocps: str | None = None) -> str:
    """A railML 2.3 file of the same line (tracks tr1, tr2, tr3 in track orientation west → east)."""
    tr1 = """
    <track id="tr1" name="T1">
      <trackTopology>
        <trackBegin id="tb1" pos="0.0"><openEnd id="oe1"/></trackBegin>
        <trackEnd id="te1" pos="3000.0"><connection id="c12" ref="c21"/></trackEnd>
        <crossSections><crossSection id="cs1" pos="500.0" ocpRef="W"/></crossSections>
      </trackTopology>
      <trackElements>
        <speedChanges>
          <speedChange id="v1" pos="0.0" dir="up" vMax="100"/>
          <speedChange id="v2" pos="1200.0" dir="up" vMax="80"/>
          <speedChange id="v3" pos="1600.0" dir="up" vMax="100"/>
          <speedChange id="v4" pos="1600.0" dir="down" vMax="80"/>
          <speedChange id="v5" pos="1200.0" dir="down" vMax="100"/>
        </speedChanges>
        <gradientChanges>
          <gradientChange id="g1" pos="0.0" slope="5.0"/>
          <gradientChange id="g2" pos="1000.0" slope="0.0"/>
          <gradientChange id="g3" pos="1500.0" slope="-8.0"/>
          <gradientChange id="g4" pos="2500.0" slope="0.0"/>
        </gradientChanges>
        <radiusChanges>
          <radiusChange id="r1" pos="1200.0" radius="-600.0"/>
          <radiusChange id="r2" pos="1600.0" radius="0"/>
        </radiusChanges>
        <platformEdges><platformEdge id="pe1" pos="400.0" length="200.0" ocpRef="W"/></platformEdges>
      </trackElements>
      <ocsElements>
        <signals>
          <signal id="SIG1" pos="2800.0" dir="up" type="main"/>
          <signal id="DS1" pos="2000.0" dir="up" type="distant"/>
        </signals>
      </ocsElements>
    </track>"""
    tr2 = """
    <track id="tr2" name="T2">
      <trackTopology>
        <trackBegin id="tb2" pos="0.0"><connection id="c21" ref="c12"/></trackBegin>
        <trackEnd id="te2" pos="2000.0"><connection id="c23" ref="c32"/></trackEnd>
        <crossSections><crossSection id="cs2" pos="1000.0" ocpRef="M"/></crossSections>
      </trackTopology>
      <trackElements>
        <speedChanges>
          <speedChange id="v6" pos="500.0" dir="down" vMax="60"/>
          <speedChange id="v7" pos="100.0" dir="down" vMax="100"/>
        </speedChanges>
        <gradientChanges>
          <gradientChange id="g5" pos="0.0" slope="0"/>
          <gradientChange id="g6" pos="200.0" slope="-6.0"/>
          <gradientChange id="g7" pos="1800.0" slope="0"/>
        </gradientChanges>
      </trackElements>
      <ocsElements>
        <signals><signal id="SIG2" pos="1700.0" dir="up" type="main"/></signals>
        <stopPosts>
          <stopPost id="sp1" pos="1100.0" dir="up" ocpStationRef="M"/>
          <stopPost id="sp2" pos="900.0" dir="down" ocpStationRef="M"/>
        </stopPosts>
      </ocsElements>
    </track>"""
    tr3 = """
    <track id="tr3" name="T3">
      <trackTopology>
        <trackBegin id="tb3" pos="0.0"><connection id="c32" ref="c23"/></trackBegin>
        <trackEnd id="te3" pos="1500.0"><openEnd id="oe3"/></trackEnd>
        <crossSections><crossSection id="cs3" pos="1200.0" ocpRef="E"/></crossSections>
      </trackTopology>
      <trackElements>
        <speedChanges><speedChange id="v8" pos="1500.0" dir="down" vMax="100"/></speedChanges>
        <gradientChanges>
          <gradientChange id="g8" pos="0.0" slope="3.0"/>
          <gradientChange id="g9" pos="700.0" slope="0.0"/>
        </gradientChanges>
        <radiusChanges>
          <radiusChange id="r3" pos="300.0" radius="800.0"/>
          <radiusChange id="r4" pos="800.0" radius="0"/>
        </radiusChanges>
      </trackElements>
      <ocsElements>
        <signals><signal id="SIG3" pos="100.0" dir="down" type="main"/></signals>
        <balises><balise id="BC1" pos="1000.0" dir="down"/></balises>
        <trainDetectionElements><trainDetector id="D1" pos="1000.0"/></trainDetectionElements>
      </ocsElements>
    </track>"""
    if tracks is None:
        tracks = tr1 + tr2 + tr3
    if lines is None:
        lines = """
    <line id="L1" name="Test line">
      <trackRef ref="tr1" sequence="1"/><trackRef ref="tr2" sequence="2"/><trackRef ref="tr3" sequence="3"/>
    </line>"""
    if ocps is None:
        ocps = """
    <ocp id="W" name="West"><propOperational operationalType="station"/></ocp>
    <ocp id="M" name="Middle"><propOperational operationalType="station"/></ocp>
    <ocp id="E" name="East"><propOperational operationalType="station"/></ocp>"""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<railml xmlns="{RAILML_NS}" version="2.3">
 <infrastructure id="is1">
  <tracks>{tracks}
  </tracks>
  <trackGroups>{lines}
  </trackGroups>
  <operationControlPoints>{ocps}
  </operationControlPoints>
 </infrastructure>
</railml>
"""


def write_railml(folder: Path, text: str | None = None) -> tuple[Path, Path, Path]:
    """Write line.railml, emu.json and extra.toml into ``folder``; return their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    f, r, x = folder / "line.railml", folder / "emu.json", folder / "extra.toml"
    f.write_text(railml_text() if text is None else text)
    r.write_text(json.dumps(rolling_stock(), indent=1))
    x.write_text(EXTRA_TOML.replace('at = "D1"\n', ""))
    return f, r, x
