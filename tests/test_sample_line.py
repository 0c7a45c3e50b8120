"""The sample line ``lines/sample``: reproducible from its build script, and shaped the way later
features rely on (the hard stopping approach, beacons, signals, timetable, network).

The checks read the committed Parquet files with pandas and recompute every property from the
data itself; none of them imports the build script's own figures.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "lines" / "sample"
TABLES = ("line", "stations", "gradients", "curves", "speed_limits", "beacons", "signals",
          "rolling_stock", "traction", "timetable", "nodes", "edges")
G = 9.80665
EPS_M = 1e-6   # chainages are whole metres in the build; anything closer is "the same point"


def read(name: str) -> pd.DataFrame:
    return pq.read_table(SAMPLE / f"{name}.parquet").to_pandas()


@pytest.fixture(scope="module")
def db() -> dict[str, pd.DataFrame]:
    return {name: read(name) for name in TABLES}


# ------------------------------------------------------------------ reproducibility

def test_build_script_reproduces_committed_files(tmp_path):
    r = subprocess.run([sys.executable, str(SAMPLE / "build.py"), "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.glob("*.parquet")) == sorted(f"{t}.parquet" for t in TABLES)
    for name in TABLES:
        fresh = pq.read_table(tmp_path / f"{name}.parquet")
        committed = pq.read_table(SAMPLE / f"{name}.parquet")
        assert fresh.schema.equals(committed.schema, check_metadata=True), name
        assert fresh.equals(committed, check_metadata=True), f"{name}.parquet differs from a fresh build"
        # the bytes too: the build writes the declared form with the importers' writer (CSV round trip)
        assert (tmp_path / f"{name}.parquet").read_bytes() == (SAMPLE / f"{name}.parquet").read_bytes(), name
    assert not list(tmp_path.glob("*.tmp")), "temporary files left behind"


def test_column_types_follow_schema_md():
    types = {
        "line": {"line_id": "string", "start_m": "double", "end_m": "double",
                 "max_speed_kmh": "double", "schema_version": "int32"},
        "timetable": {"seq": "int32", "arrival_s": "double", "departure_s": "double", "stops": "bool"},
        "speed_limits": {"limit_kmh": "double", "has_beacon": "bool", "train_type": "string"},
        "beacons": {"evaluation_point": "bool", "position_m": "double"},
        "rolling_stock": {"davis_c_kN_per_kmh2": "double", "cruise": "string"},
    }
    for name, cols in types.items():
        schema = pq.read_schema(SAMPLE / f"{name}.parquet")
        for col, t in cols.items():
            assert str(schema.field(col).type) == t, (name, col)
        assert schema.metadata is None or b"pandas" not in schema.metadata, name


# ------------------------------------------------------------------ line and stations

def test_line_size(db):
    line, st = db["line"], db["stations"]
    assert len(line) == 1 and line.line_id[0] == "sample" and line.max_speed_kmh[0] == 100.0
    assert line.schema_version[0] == 2
    assert 10 <= len(st) <= 14
    assert 25_000 <= st.position_m.iloc[-1] - st.position_m.iloc[0] <= 30_000
    assert st.position_m.is_monotonic_increasing
    gaps = np.diff(st.position_m)
    assert np.any(np.abs(gaps - 3000) <= 200) and np.any(np.abs(gaps - 7000) <= 300)
    assert gaps.min() >= 1000


def test_stop_markers_on_platform_and_inside_line(db):
    st, line = db["stations"], db["line"].iloc[0]
    half = st.platform_length_m / 2
    for col in ("stop_down_m", "stop_up_m"):
        assert (st[col] >= line.start_m).all() and (st[col] <= line.end_m).all()
        assert (np.abs(st[col] - st.position_m) <= half).all()
    assert ((st.stop_down_m - st.position_m).between(90, 105)).all()
    assert ((st.position_m - st.stop_up_m).between(90, 105)).all()
    assert st.platform_length_m.between(200, 210).all()


def test_gradients_within_ten_permil_except_the_approach(db):
    g = db["gradients"]
    assert (g.start_m < g.end_m).all() and (g.start_m.iloc[1:].values >= g.end_m.iloc[:-1].values).all()
    steep = g[g.gradient_permil.abs() > 10]
    assert len(steep) == 1 and steep.gradient_permil.iloc[0] == -20.0
    assert (steep.end_m - steep.start_m).iloc[0] == 150.0


def _gradient_integral(g: pd.DataFrame, a: float, b: float) -> float:
    """∫ gradient dx over [a, b] [‰·m]; gaps are level."""
    lo, hi = np.maximum(g.start_m, a), np.minimum(g.end_m, b)
    return float((np.clip(hi - lo, 0, None) * g.gradient_permil).sum())


def test_hard_station_approach_exists(db):
    """Some station, in some direction: over the last 350 m before its stop marker the first 150 m
    fall at 20 ‰ and the rest is level; 70 km/h before it, 40 km/h (and a curve) over the last 100 m."""
    g, lim, cur = db["gradients"], db["speed_limits"], db["curves"]
    found = []
    for _, s in db["stations"].iterrows():
        for direction, sg, stop in (("down", 1, s.stop_down_m), ("up", -1, s.stop_up_m)):
            def span(d0, d1):   # chainage interval d0..d1 metres before the marker
                a, b = stop - sg * d1, stop - sg * d0
                return min(a, b), max(a, b)
            a, b = span(200, 350)
            falls = ((g.start_m == a) & (g.end_m == b) & (g.gradient_permil == -20 * sg)).any()
            level = _gradient_integral(g, *span(0, 200)) == 0 and not (
                (g.start_m < span(0, 200)[1]) & (g.end_m > span(0, 200)[0])).any()
            if not (falls and level):
                continue
            applies = lim.direction.isin(["both", direction]) & lim.train_type.isna()
            a40, b40 = span(0, 100)
            has40 = (applies & (lim.limit_kmh == 40) & (lim.start_m == a40) & (lim.end_m == b40)).any()
            curve40 = ((cur.start_m <= a40) & (cur.end_m >= b40)).any()
            edge = stop - sg * 350          # the 70 km/h restriction ends where the 350 m begin
            near = lim.end_m if sg == 1 else lim.start_m
            far = lim.start_m if sg == 1 else lim.end_m
            has70 = (applies & (lim.limit_kmh == 70) & (np.abs(near - edge) < EPS_M)
                     & ((far - edge).abs() >= 200)).any()
            # nothing else restricts the last 350 m
            lo, hi = span(0, 350)
            inside = applies & (lim.start_m < hi) & (lim.end_m > lo) & (lim.limit_kmh != 40)
            if has40 and curve40 and has70 and not inside.any():
                found.append((s.station_id, direction))
    assert found, "no station approach with the -20 permil / level / 70 / 40 km/h shape"


# ------------------------------------------------------------------ restrictions, beacons, signals

def test_restriction_kinds_and_close_unbeaconed_pair(db):
    lim = db["speed_limits"]
    assert {"curve", "turnout", "civil"} <= set(lim.kind)
    assert lim.limit_kmh.max() < 100 and lim.limit_kmh.min() > 0
    cur = db["curves"]
    curve_lims = lim[lim.kind == "curve"]
    for _, r in curve_lims.iterrows():    # every curve restriction sits on a curve of the curves table
        assert ((cur.start_m <= r.start_m) & (cur.end_m >= r.end_m)).any(), r
    ordinary = curve_lims.merge(cur, on=["start_m", "end_m"])
    ordinary = ordinary[ordinary.radius_m.between(400, 800)]
    assert len(ordinary) >= 3 and ordinary.limit_kmh.between(70, 90).all()
    no = lim[~lim.has_beacon].sort_values("start_m")
    starts = no.start_m.to_numpy()
    assert len(no) >= 2 and np.any(np.diff(starts) < 200)


def _running_order(b: pd.DataFrame, direction: str) -> pd.DataFrame:
    b = b[b.direction == direction]
    return b.sort_values("position_m", ascending=(direction == "down")).reset_index(drop=True)


def test_consecutive_identical_telegrams(db):
    longest = 0
    for direction in ("down", "up"):
        tel = _running_order(db["beacons"], direction).telegram.tolist()
        run = 1
        for x, y in zip(tel[:-1], tel[1:]):
            run = run + 1 if x == y else 1
            longest = max(longest, run)
    assert longest >= 3


def test_beacon_flags_and_ids(db):
    b = db["beacons"]
    assert b.beacon_id.is_unique
    assert set(b.kind) == {"signal", "pattern_update", "tasc"}
    assert b[b.kind.isin(["signal", "pattern_update"])].evaluation_point.all()
    assert not b[b.kind == "tasc"].evaluation_point.any()
    for direction in ("down", "up"):   # no two beacons of one direction on the same spot
        assert np.diff(np.sort(b[b.direction == direction].position_m)).min() >= 10


def _signals_in_running_order(sig: pd.DataFrame, direction: str) -> pd.DataFrame:
    s = sig[sig.direction == direction]
    return s.sort_values("position_m", ascending=(direction == "down")).reset_index(drop=True)


def test_station_signals_at_every_station(db):
    """Each direction: starting signal just beyond every stop marker it departs from, home signal
    at the entrance of every station it arrives at — outside the platform and before the throat
    switches on its main track — and only automatic block signals in between.

    Geometry from stations/nodes alone: the platform is centre ± length/2, the throat switches are
    the ``switch`` nodes of the direction's main (D1/U1) within 600 m before the stop marker."""
    sig, st, nodes = db["signals"], db["stations"], db["nodes"]
    assert set(sig.kind) == {"home", "starting", "block"}
    for direction, sg, col, main in (("down", 1, "stop_down_m", "D1"), ("up", -1, "stop_up_m", "U1")):
        order = st.sort_values("position_m", ascending=(direction == "down")).reset_index(drop=True)
        s = _signals_in_running_order(sig, direction)
        sw = nodes[(nodes.kind == "switch") & (nodes.track == main)].position_m.to_numpy()
        starts, homes = s[s.kind == "starting"], s[s.kind == "home"]
        assert len(starts) == len(homes) == len(order) - 1
        for (_, dep), (_, arr), x_s, x_h in zip(order.iloc[:-1].iterrows(), order.iloc[1:].iterrows(),
                                                starts.position_m, homes.position_m):
            past = sg * (x_s - dep[col])
            assert 0 < past <= 50, (direction, dep.station_id, past)
            ahead = sw[(sg * (sw - dep[col]) > 0) & (sg * (sw - dep[col]) <= 200)]
            assert (sg * (ahead - x_s) > 0).all(), (direction, dep.station_id)   # short of exit switches
            entry = arr.position_m - sg * arr.platform_length_m / 2
            before_marker = sg * (arr[col] - x_h)
            assert sg * (entry - x_h) >= 50 and before_marker <= 450, (direction, arr.station_id)
            throat = sw[(sg * (arr[col] - sw) > 0) & (sg * (arr[col] - sw) <= 600)]
            assert (sg * (throat - x_h) >= 30).all(), (direction, arr.station_id)  # before every switch
        # kinds in running order: starting, block..., home, starting, block..., home, ...
        kinds = "".join(k[0] for k in s.kind)
        assert kinds.startswith("s") and kinds.endswith("h")
        assert all(seg.startswith("s") and seg.endswith("h") and set(seg[1:-1]) <= {"b"}
                   for seg in kinds.replace("hs", "h|s").split("|")), kinds


def test_signal_spacing_and_signal_beacons(db):
    """Issue 2's "block signals every 550–1,000 m" holds for the automatic block sections: every
    block from a starting signal through the automatic block signals to the next home signal is
    550–1,000 m long. The station section home -> starting (through the platform, ~335–460 m) is
    shorter by nature and is not a block of the automatic block system, so it is not checked here
    (test_station_signals_at_every_station places those signals)."""
    sig, b = db["signals"], db["beacons"]
    assert sig.signal_id.is_unique
    for direction, sg in (("down", 1), ("up", -1)):
        s = _signals_in_running_order(sig, direction)
        x = s.position_m.to_numpy()
        blocks = np.abs(np.diff(x))[(s.kind.iloc[:-1] != "home").to_numpy()]   # not home -> starting
        assert len(blocks) >= 30
        assert blocks.min() >= 550 and blocks.max() <= 1000, (direction, blocks.min(), blocks.max())
        beac = b[(b.direction == direction) & (b.kind == "signal")].position_m.to_numpy()
        for y in x:   # an ATS-P beacon a short distance before every signal
            before = sg * (y - beac)
            assert ((before > 0) & (before <= 50)).any(), (direction, y)


def test_last_evaluation_point_near_every_arrival(db):
    """With a home signal at every station entrance, the last evaluation-point beacon before each
    arrival stop marker is a few hundred metres away (250–500 m), not a whole block."""
    st, b = db["stations"], db["beacons"]
    for direction, col, sg, arrivals in (("down", "stop_down_m", 1, st.iloc[1:]),
                                         ("up", "stop_up_m", -1, st.iloc[:-1])):
        ev = b[(b.direction == direction) & b.evaluation_point].position_m.to_numpy()
        for stop in arrivals[col]:
            before = sg * (stop - ev)
            last = before[before > 0].min()
            assert 250 <= last <= 500, (direction, stop, last)


def test_tasc_before_every_arrival_stop_marker(db):
    st, b = db["stations"], db["beacons"]
    for direction, col, sg, arrivals in (("down", "stop_down_m", 1, st.iloc[1:]),
                                         ("up", "stop_up_m", -1, st.iloc[:-1])):
        tasc = b[(b.direction == direction) & (b.kind == "tasc")].position_m.to_numpy()
        assert len(tasc) == len(arrivals)
        for stop in arrivals[col]:
            before = sg * (stop - tasc)
            # lines/sample/README.md: at least 550 m, in whole 50 m, no farther than a block
            assert ((before >= 550) & (before <= 1000) & (before % 50 == 0)).any(), (direction, stop)


def test_pattern_update_beacons_before_beaconed_restrictions(db):
    lim, b = db["speed_limits"], db["beacons"]
    for direction, sg in (("down", 1), ("up", -1)):
        pu = b[(b.direction == direction) & (b.kind == "pattern_update")].position_m.to_numpy()
        mine = lim[lim.has_beacon & lim.direction.isin(["both", direction])]
        near = mine.start_m if sg == 1 else mine.end_m
        for x in near:
            before = sg * (x - pu)
            assert ((before > 0) & (before <= 600)).any(), (direction, x)


# ------------------------------------------------------------------ rolling stock

def test_rolling_stock_is_plausible(db):
    rs, tr = db["rolling_stock"].set_index("train_type"), db["traction"]
    assert 2 <= len(rs) <= 3
    assert set(rs.cruise) == {"constant", "sawtooth"}
    per_car_empty = rs.empty_mass_t / (rs.length_m / 20)
    per_car_load = rs.full_load_mass_t / (rs.length_m / 20)
    assert per_car_empty.between(25, 35).all() and per_car_load.between(10, 17).all()
    assert rs.rotating_mass_factor.between(0.05, 0.12).all()
    assert rs.service_brake_kmh_s.between(3.5, 4.2).all()
    assert rs.stop_brake_kmh_s.between(3.0, 3.5).all()
    assert (rs.atsp_pattern_kmh_s <= rs.service_brake_kmh_s).all()
    assert rs.speed_margin_kmh.between(3, 5).all()
    for tt, r in rs.iterrows():
        c = tr[tr.train_type == tt].sort_values("speed_kmh")
        v, f = c.speed_kmh.to_numpy(), c.effort_kN.to_numpy()
        assert v[0] == 0 and v[-1] >= r.max_speed_kmh + 10 and np.all(np.diff(v) == 5)
        assert np.all(np.diff(f) <= 1e-9)               # effort never rises with speed
        const = f == f[0]
        assert 30 <= v[const].max() <= 45                # constant-effort region up to the base speed
        vb = v[const].max()
        # then constant power for a while: F·v stays at F0·vb just above the base speed
        above = (v > vb) & (v <= vb + 20)
        np.testing.assert_allclose(f[above] * v[above], f[0] * vb, rtol=0.01)

        def resist(vk, load, permil):
            m = r.empty_mass_t + load * r.full_load_mass_t
            return r.davis_a_kN + r.davis_b_kN_per_kmh * vk + r.davis_c_kN_per_kmh2 * vk ** 2 + m * G * permil / 1000

        # starting acceleration at half load ≈ the nominal one (within 0.15 km/h/s)
        me = (r.empty_mass_t + 0.5 * r.full_load_mass_t) * (1 + r.rotating_mass_factor)
        assert abs((f[0] - r.davis_a_kN) / me * 3.6 - r.max_accel_kmh_s) <= 0.15, tt
        target = min(100.0, r.max_speed_kmh) - r.speed_margin_kmh
        assert np.interp(target, v, f) > resist(target, 0.5, 10.0), tt       # holds on +10 ‰
        assert np.interp(100.0, v, f) > resist(100.0, 0.0, 0.0), tt          # > 100 km/h empty, level


# ------------------------------------------------------------------ timetable

def test_timetable_shape(db):
    tt, st = db["timetable"], db["stations"]
    pos = st.set_index("station_id").position_m
    assert tt.train_type.isin(db["rolling_stock"].train_type).all()
    n_st = len(st)
    for (tid, direction), t in tt.groupby(["train_id", "direction"]):
        t = t.sort_values("seq")
        assert list(t.seq) == list(range(len(t))) and len(t) == n_st, tid
        x = pos[t.station_id].to_numpy()
        assert np.all(np.diff(x) > 0) if direction == "down" else np.all(np.diff(x) < 0), tid
        assert np.isnan(t.arrival_s.iloc[0]) and np.isnan(t.departure_s.iloc[-1]), tid
        times = np.column_stack([t.arrival_s, t.departure_s]).ravel()
        times = times[~np.isnan(times)]
        assert np.all(np.diff(times) >= 0), tid
        assert np.all(times % 5 == 0), tid
        passes = t[~t.stops]
        assert (passes.arrival_s == passes.departure_s).all(), tid
    first = tt[tt.seq == 0].departure_s
    assert first.min() <= 5 * 3600 + 600 and first.max() >= 23 * 3600


def test_locals_and_rapids(db):
    tt = db["timetable"]
    per_train = tt.groupby("train_id").stops.agg(["all", "sum"])
    locals_, rapids = per_train[per_train["all"]], per_train[~per_train["all"]]
    assert len(rapids) >= 2 * 30 and len(locals_) >= 2 * 100
    n = tt.station_id.nunique()
    assert rapids["sum"].between(n // 2 - 1, n // 2 + 2).all()   # about half the stations
    # peak (07:00-09:00) headway of locals from the origin about 6 min, off-peak about 10
    dep = tt[(tt.seq == 0) & tt.train_id.isin(locals_.index) & (tt.direction == "down")].departure_s
    peak = np.diff(np.sort(dep[(dep >= 7 * 3600) & (dep < 9 * 3600)]))
    mid = np.diff(np.sort(dep[(dep >= 11 * 3600) & (dep < 15 * 3600)]))
    assert 5 * 60 <= peak.mean() <= 7 * 60 and 9 * 60 <= mid.mean() <= 11 * 60


def test_overtakes_happen_only_where_there_is_a_loop(db):
    """A local overtaken by a rapid waits at a station with a loop, longer than an ordinary dwell;
    found from the times alone: the rapid passes or leaves while the local stands."""
    tt, nodes = db["timetable"], db["nodes"]
    loop_stations = set(nodes[(nodes.kind == "stop") & nodes.track.str.endswith("2")].station_id)
    assert 2 <= len(loop_stations) <= 3
    rapids = set(tt.groupby("train_id").stops.all().loc[lambda s: ~s].index)
    seen = set()
    for (direction, sid), here in tt.groupby(["direction", "station_id"]):
        loc = here[~here.train_id.isin(rapids) & here.arrival_s.notna() & here.departure_s.notna()]
        rap = here[here.train_id.isin(rapids)]
        for _, l in loc.iterrows():
            by = rap[(rap.departure_s > l.arrival_s) & (rap.departure_s < l.departure_s)]
            if len(by):
                assert sid in loop_stations, (l.train_id, sid)
                assert l.departure_s - l.arrival_s >= 120, (l.train_id, sid)
                seen.add((direction, sid))
    assert {d for d, _ in seen} == {"down", "up"}
    assert {s for _, s in seen} == loop_stations      # every loop is used


def test_running_time_margins_against_the_simulator(db):
    """Scheduled E10 local running times follow the planner's rule in lines/sample/README.md, checked
    with planner's own simulator (not the build's estimate): ceil_5s(standard x 1.08 + 10 s) with the
    standard = simulated minimum at the design load 0.5, except the two deliberately short legs
    KWB->HGO down (1.5 %, 0 s) and OHS->TKD up (0 %, 10 s)."""
    planner = pytest.importorskip("planner")
    try:
        from planner.api import running_time  # noqa: F401
    except ImportError:
        pytest.skip("run-curve simulator not available")
    rule = {("KWB", "HGO"): (1.5, 0.0), ("OHS", "TKD"): (0.0, 10.0)}  # README.md, "Running times"
    line = planner.load_line(SAMPLE)
    tt = db["timetable"]
    rapids = set(tt.groupby("train_id").stops.all().loc[lambda s: ~s].index)
    e10 = tt[(tt.train_type == "E10") & ~tt.train_id.isin(rapids)]
    seen = 0
    for direction in ("down", "up"):
        t = e10[e10.direction == direction].sort_values(["train_id", "seq"])
        nxt = t.groupby("train_id").shift(-1)
        runs = pd.DataFrame({"a": t.station_id, "b": nxt.station_id,
                             "run": nxt.arrival_s - t.departure_s}).dropna()
        assert (runs.groupby(["a", "b"]).run.nunique() == 1).all()   # same for every E10 local
        for (a, b), s in runs.groupby(["a", "b"]).run.min().items():
            standard = planner.running_time(line, "E10", a, b, load=0.5).time_s
            pct, per_leg = rule.get((a, b), (8.0, 10.0))
            target = standard * (1 + pct / 100) + per_leg
            # rounded up to 5 s; the build's own estimate agrees with the simulator to 0.05 %
            assert s % 5 == 0 and -0.001 * standard <= s - target < 5.0, (a, b, s, target)
            seen += 1
    assert seen == 2 * 11


# ------------------------------------------------------------------ track network

def test_network_geometry(db):
    nodes, edges, st = db["nodes"], db["edges"], db["stations"]
    assert nodes.node_id.is_unique and edges.edge_id.is_unique
    assert set(nodes.kind) == {"switch", "stop", "boundary", "end"}
    pos = nodes.set_index("node_id").position_m
    assert (edges.length_m > 0).all()
    np.testing.assert_allclose(edges.length_m, np.abs(pos[edges.to_node].values - pos[edges.from_node].values))
    # each main track is one chain from end to end, through a stop node at every station
    for track, col in (("D1", "stop_down_m"), ("U1", "stop_up_m")):
        e = edges[edges.track == track]
        chain = list(e.sort_values("edge_id").from_node) + [e.sort_values("edge_id").to_node.iloc[-1]]
        x = pos[chain].to_numpy()
        assert np.all(np.diff(x) > 0) and x[0] == db["line"].start_m[0] and x[-1] == db["line"].end_m[0]
        stops = nodes[(nodes.kind == "stop") & (nodes.track == track)]
        assert sorted(stops.station_id) == sorted(st.station_id)
        np.testing.assert_allclose(np.sort(stops.position_m), np.sort(st[col]))
    # loops: switch -> stop -> switch on a D2/U2 track, beside the main of the same direction
    for track in ("D2", "U2"):
        e = edges[edges.track == track]
        assert len(e) % 2 == 0 and len(e) >= 4
        ends = nodes.set_index("node_id").loc[list(e.from_node) + list(e.to_node)]
        assert set(ends.kind) == {"switch", "stop"}
        assert set(ends[ends.kind == "switch"].track) == {track[0] + "1"}
    # crossovers join D1 and U1
    x = edges[~edges.track.str.match(r"^[DU][12]$")]
    assert len(x) >= 5
    tr = nodes.set_index("node_id").track
    assert all({tr[a], tr[b]} == {"D1", "U1"} for a, b in zip(x.from_node, x.to_node))
    # interlockings: several, each a contiguous stretch; boundary nodes on both mains
    assert nodes.interlocking.nunique() >= 3
    bnd = nodes[nodes.kind == "boundary"]
    assert len(bnd) == 2 * (nodes.interlocking.nunique() - 1)
    for track in ("D1", "U1"):
        seq = nodes[nodes.track == track].sort_values("position_m").interlocking
        assert (seq != seq.shift()).sum() == nodes.interlocking.nunique()


def test_every_sample_approach_has_a_pattern_at_the_nightly_adhesion_levels():
    """Issue 17: the sample's TASC beacons stand where a real line puts them, so the nightly stop sweep
    finds a pattern for every approach at every adhesion level (a beacon too close for its approach
    speed is still reported: tests/test_stops.py, tests/test_margins.py)."""
    import tomllib
    import warnings

    import planner
    from planner.stopping.sweep import InfeasibleStopWarning, stop_sweep

    spec = tomllib.loads((ROOT / "jobs" / "nightly.toml").read_text())["stops"]["adhesion_kmh_s"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InfeasibleStopWarning)
        results = stop_sweep(planner.load_line(SAMPLE), adhesion_kmh_s=spec, n_jobs=1)
    assert len(results) == 66  # 11 stops per direction x 2 directions x 3 train types
    bad = [f"{r.train_type} {r.direction} {r.origin}->{r.station_id} at {a} m/s²: {p.reason}"
           for r in results for a, p in zip(r.adhesion_ms2, r.patterns) if not p.feasible]
    assert not bad, "\n".join(bad)
