"""Public API ``planner.running_time`` / ``RunResult`` and the ``planner runtime`` command."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import planner
from planner.line import testing
from planner.cli import app as cli_app
from planner.errors import InputError
from planner.physics.run_curve import PHASE_NAMES, simulate
from planner.physics.track import make_track
from planner.line.units import KMH

SAMPLE = Path(__file__).resolve().parents[1] / "lines" / "sample"


def small_line():
    tt = testing.train_type(davis_a_kN=4, davis_c_kN_per_kmh2=0.001)
    return testing.line(length_m=5000, stations=[0, 2000, 5000], limits=[(2800, 3200, 45)],
                        gradients=[(1000, 4000, 8)], train_types=[tt])


def test_running_time_result_and_curve():
    line = small_line()
    res = planner.running_time(line, "T", "S1", "S0", ratio=0.8, load=0.5, traction_factor=0.9)
    assert isinstance(res, planner.RunResult)
    assert res.direction == "up" and res.length_m == pytest.approx(2000)
    tr = make_track(line, "T", "S1", "S0")
    ref = simulate(tr, line.train_type("T"), 0.8, load=0.5, traction_factor=0.9)
    assert res.time_s == pytest.approx(float(ref.time_s[0]), abs=1e-9)
    assert res.energy_kwh == pytest.approx(float(ref.energy_kwh[0]), abs=1e-9)
    c = res.curve
    assert {"position_m", "time_s", "speed_kmh", "accel_ms2", "phase"} <= set(c.columns)
    assert c["position_m"].iloc[0] == 2000 and c["position_m"].iloc[-1] == 0  # chainage, running up
    assert c["time_s"].iloc[-1] == pytest.approx(res.time_s)
    assert c["speed_kmh"].iloc[-1] == 0
    assert set(c["phase"].astype(str)) <= set(PHASE_NAMES)
    assert (c["speed_kmh"] <= c["target_kmh"] + 1e-6).all()


def test_ratio_changes_are_chainages():
    line = small_line()
    # down from S1 (2000) to S2 (5000): chainage 2600 is 600 m after departure
    res = planner.running_time(line, "T", "S1", "S2", ratio=1.0, ratio_changes=[(2600.0, 0.5)])
    tr = make_track(line, "T", "S1", "S2", nodes_m=[600.0])
    ref = simulate(tr, line.train_type("T"), 1.0, changes=[(600.0, np.array([0.5]))])
    assert res.time_s == pytest.approx(float(ref.time_s[0]), abs=1e-9)
    after = res.curve[res.curve["position_m"] > 2600]
    assert (after["ratio"] == 0.5).all()
    with pytest.raises(InputError, match="position_m=100"):
        planner.running_time(line, "T", "S1", "S2", ratio_changes=[(100.0, 0.5)])
    with pytest.raises(InputError, match="ratio"):
        planner.running_time(line, "T", "S1", "S2", ratio=0.0)


def test_running_time_from_a_path(monkeypatch, tmp_path):
    line = small_line()
    seen = []

    def fake_load(path):
        seen.append(path)
        return line

    import planner.line.loader

    monkeypatch.setattr(planner.line.loader, "load_line", fake_load)
    res = planner.running_time(tmp_path, "T", "S0", "S1")
    assert seen == [tmp_path] and res.time_s > 0


@pytest.fixture(scope="module")
def sample_ids():
    try:
        line = planner.load_line(SAMPLE)
    except (ImportError, FileNotFoundError, OSError) as e:
        pytest.skip(f"sample line not loadable: {e}")
    a, b = line.interstations("down")[0]
    return line.train_types[0].train_type, a.station_id, b.station_id


def test_cli_json_and_plot(sample_ids, tmp_path):
    tt, a, b = sample_ids
    png = tmp_path / "curve.png"
    r = CliRunner().invoke(cli_app, ["runtime", str(SAMPLE), "--train-type", tt, "--from", a,
                                             "--to", b, "--ratio", "0.8", "--json", "--plot", str(png)])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)  # the JSON alone on stdout; stderr says which line it ran on
    assert r.stderr.startswith("note: the line as its database has it, no operating day's temporary restrictions")
    ref = planner.running_time(SAMPLE, tt, a, b, ratio=0.8)
    assert out["running_time_s"] == pytest.approx(ref.time_s, abs=1e-3)
    assert out["energy_kwh"] == pytest.approx(ref.energy_kwh, abs=1e-3)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp file left
    r = CliRunner().invoke(cli_app, ["runtime", str(SAMPLE), "--train-type", tt, "--from", a, "--to", b])
    assert r.exit_code == 0 and "running time" in r.output


def test_cli_bad_input_is_one_line(sample_ids):
    tt, a, b = sample_ids
    p = subprocess.run([sys.executable, "-c", "from planner.cli import main; main()", "runtime", str(SAMPLE),
                        "--train-type", tt, "--from", a, "--to", b, "--ratio", "1.5"],
                       capture_output=True, text=True)
    assert p.returncode != 0
    assert "--ratio" in p.stderr and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1
    p = subprocess.run([sys.executable, "-c", "from planner.cli import main; main()", "runtime", str(SAMPLE),
                        "--train-type", "NOPE", "--from", a, "--to", b], capture_output=True, text=True)
    assert p.returncode != 0 and "NOPE" in p.stderr and "Traceback" not in p.stderr


def test_top_speed_matches_limit_on_sample(sample_ids):
    tt, a, b = sample_ids
    res = planner.running_time(SAMPLE, tt, a, b)
    assert (res.curve["speed_kmh"] <= res.curve["vmax_kmh"] + 1e-6).all()
    assert res.curve["vmax_kmh"].max() <= planner.load_line(SAMPLE).max_speed_ms / KMH + 1e-9
