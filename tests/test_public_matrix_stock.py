"""The public-data matrix (benchmarks/public_matrix.py) writes TrainRuns.jl's train types as OSRD rolling-stock
JSON: importing that JSON must give back the figures tests/public_trains.py types in, or the matrix would run
other trains than the ones it names."""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

from planner.line.importers.common import ImportSummary, load_extras
from planner.line.importers.stock import read_rolling_stock
from public_trains import tr_dmu, tr_freight, tr_ic

ROOT = Path(__file__).resolve().parents[1]


def _matrix():
    spec = importlib.util.spec_from_file_location("public_matrix", ROOT / "benchmarks" / "public_matrix.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # its dataclass looks its module up
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("make", [tr_dmu, tr_ic, tr_freight])
def test_trainruns_types_survive_the_osrd_json_round_trip(tmp_path, make):
    tt = make()
    rs, over = _matrix()._trainruns_stock(tt)
    f = tmp_path / "rs.json"
    f.write_text(json.dumps(rs))
    x = tmp_path / "x.toml"
    x.write_text(f"[rolling_stock.{tt.train_type}]\n" + "".join(f"{k} = {v!r}\n" for k, v in over.items()))
    s = ImportSummary(str(f), extra=load_extras(x))
    name, row, traction = read_rolling_stock(f, s)
    kmh = 3.6
    assert name == tt.train_type
    assert row["length_m"] == pytest.approx(tt.length_m)
    assert row["empty_mass_t"] == pytest.approx(tt.empty_mass_kg / 1000)
    assert (row["full_load_mass_t"] or 0.0) == pytest.approx(tt.full_load_mass_kg / 1000)
    assert row["max_speed_kmh"] == pytest.approx(tt.max_speed_ms * kmh)
    assert row["rotating_mass_factor"] == pytest.approx(tt.rotating_mass_factor)
    assert row["davis_a_kN"] == pytest.approx(tt.davis_a_N / 1000)
    assert row["davis_c_kN_per_kmh2"] == pytest.approx(tt.davis_c_N_per_ms2 / 1000 / kmh**2)
    assert row["stop_brake_kmh_s"] == pytest.approx(tt.stop_brake_ms2 * kmh)
    assert row["service_brake_kmh_s"] == pytest.approx(tt.service_brake_ms2 * kmh)
    # no acceleration cap in TrainRuns: the line database's upper bound (5 m/s² = 18 km/h/s), never below it
    assert row["max_accel_kmh_s"] == pytest.approx(18.0)
    assert [p["speed_kmh"] for p in traction] == pytest.approx(list(tt.traction_speed_ms * kmh))
    assert [p["effort_kN"] for p in traction] == pytest.approx(list(tt.traction_effort_N / 1000))
