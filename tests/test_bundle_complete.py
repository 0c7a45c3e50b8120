"""Bundle completeness follows the vehicle's cruise mode: table (d) exists only for sawtooth vehicles.

Before: every constant-speed bundle verified "PARTIAL: missing table_d" and `--require-complete`
failed for 4 of the 6 nightly bundles, with advice ("rebuild with --tables and --stops") that could
not fix it.
"""
from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from planner.bundle.container import build_bundle, build_line, bundle_bytes
from planner.bundle.manifest import EXPECTED_TABLES, expected_tables
from planner.bundle.verify import verify_bundle
from planner.cli import app
from planner.errors import BundleError
from test_bundle_support import LINE_ID, all_tables, forge, make_line, release


@pytest.fixture(scope="module")
def line():
    return make_line()


def _build(tables, out, priv, cruise):
    return build_bundle(tables, out_dir=out, private_key=priv, line_id=LINE_ID, direction="down",
                        train_type="E10", line_digest="ab" * 32,
                        expected=expected_tables(cruise), release=release())


def test_expected_tables_by_cruise_mode():
    assert "table_d" in expected_tables("sawtooth")
    assert "table_d" not in expected_tables("constant")
    assert set(expected_tables("constant")) == set(EXPECTED_TABLES) - {"table_d"}


def test_constant_speed_bundle_without_table_d_is_complete(keys, line, tmp_path):
    tables = {k: v for k, v in all_tables(line).items() if k != "table_d"}
    info = _build(tables, tmp_path, keys[0], "constant")
    v = verify_bundle(info.path, keys[1])
    assert v.complete and v.missing == ()
    assert "complete" in v.summary()[-1] and "PARTIAL" not in v.summary()[-1]
    r = CliRunner().invoke(app, ["bundle", "verify", str(info.path), "--public-key", str(keys[1]),
                                 "--expect", f"{LINE_ID}/down/E10", "--require-complete"])
    assert r.exit_code == 0, r.output


def test_sawtooth_bundle_without_table_d_is_partial_and_the_advice_names_the_fix(keys, line, tmp_path):
    tables = {k: v for k, v in all_tables(line).items() if k not in ("table_d", "stop_summary", "stop_samples")}
    info = _build(tables, tmp_path, keys[0], "sawtooth")
    v = verify_bundle(info.path, keys[1])
    assert not v.complete and v.missing == ("stop_samples", "stop_summary", "table_d")
    r = CliRunner().invoke(app, ["bundle", "verify", str(info.path), "--public-key", str(keys[1]),
                                 "--expect", f"{LINE_ID}/down/E10", "--require-complete"])
    assert r.exit_code == 1
    msg = r.stderr.strip()
    assert "\n" not in msg and "Traceback" not in r.output
    # each missing table is tied to the option whose folder provides it, nothing else is named
    assert "--tables DIR" in msg and "planner tables" in msg and "holds table_d" in msg
    assert "--stops DIR" in msg and "planner stops" in msg and "stop_samples, stop_summary" in msg


def test_advice_names_only_the_step_that_is_missing(keys, line, tmp_path):
    tables = {k: v for k, v in all_tables(line).items() if k not in ("stop_summary", "stop_samples")}
    info = _build(tables, tmp_path, keys[0], "sawtooth")
    r = CliRunner().invoke(app, ["bundle", "verify", str(info.path), "--public-key", str(keys[1]),
                                 "--expect", f"{LINE_ID}/down/E10", "--require-complete"])
    assert r.exit_code == 1 and "--stops DIR" in r.stderr and "--tables" not in r.stderr


def test_only_vehicle_tables_may_go_unlisted(keys, line, tmp_path):
    """A signer may leave table_d out of 'missing' (it knew the vehicle); never any other table."""
    tables = {k: v for k, v in all_tables(line).items() if k not in ("table_d", "table_c")}
    ok = tmp_path / "ok.pdb"
    ok.write_bytes(forge(tables, keys[2], missing=["table_c"]))
    assert verify_bundle(ok, keys[1]).missing == ("table_c",)
    bad = tmp_path / "bad.pdb"
    bad.write_bytes(forge(tables, keys[2], missing=["table_d"]))
    with pytest.raises(BundleError, match="'missing'"):
        verify_bundle(bad, keys[1])
    with pytest.raises(BundleError, match="only table_d may be left out"):
        bundle_bytes(all_tables(line), line_id=LINE_ID, direction="down", train_type="E10",
                     private_key=keys[2], expected=["table_a"], release=release())


def test_build_line_uses_each_vehicles_cruise_mode(keys, tmp_path):
    """build_line on the tiny line: a constant-speed type built from a tables folder without table_d verifies complete."""
    from linedb import write_line_db
    from planner.line.loader import load_line

    ln = load_line(write_line_db(tmp_path / "tiny"))
    types = {t.train_type: t.cruise for t in ln.train_types}
    infos = build_line(ln, tmp_path / "out", keys[0], directions=["down"], release=release())
    for info in infos:
        v = verify_bundle(info.path, keys[1])
        tt = Path(info.path).stem.split("_")[-1]
        assert ("table_d" in v.missing) == (types[tt] == "sawtooth")


def _no_pattern_at(tables, station: str, levels=(3.0, 3.5)):
    """The tables with the stop at ``station`` infeasible at ``levels`` (its stop_summary rows say so)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    ss = tables["stop_summary"]
    bad = pc.and_(pc.equal(ss.column("station_id"), station), pc.is_in(ss.column("adhesion_kmh_s"),
                                                                      value_set=pa.array(levels)))
    i = ss.column_names.index("feasible")
    return {**tables, "stop_summary": ss.set_column(i, "feasible", pc.invert(bad))}


def test_a_bundle_that_cannot_stop_its_train_at_a_station_is_not_complete_and_names_the_stop(keys, line, tmp_path):
    """A restriction left no stopping pattern at a station: the bundle held the patterns that exist and verified
    as complete. Its signed manifest now names the stop and the levels, it is PARTIAL, and --require-complete
    refuses it naming them (one line)."""
    from planner.bundle.manifest import no_stop_text

    info = verify_bundle(_build(_no_pattern_at(all_tables(line), "S2"), tmp_path, keys[0], "sawtooth").path, keys[1])
    assert not info.missing and not info.complete
    assert info.no_stop == ({"station_id": "S2", "origin": "S1", "adhesion_kmh_s": ["3.0", "3.5"]},)
    assert no_stop_text(info.no_stop) == "S2 from S1 at 3…3.5 km/h/s (2 levels)"
    assert info.summary()[-1] == "PARTIAL: no stopping pattern at S2 from S1 at 3…3.5 km/h/s (2 levels)"
    args = ["bundle", "verify", str(info.path), "--public-key", str(keys[1]), "--expect", f"{LINE_ID}/down/E10"]
    assert CliRunner().invoke(app, args).exit_code == 0  # verified: what it holds is sound, it says PARTIAL
    r = CliRunner().invoke(app, args + ["--require-complete"])
    assert r.exit_code == 1 and r.output.count("\n") == 1
    assert "incomplete, no stopping pattern at S2 from S1 at 3…3.5 km/h/s (2 levels)" in r.output


def test_a_bundle_signed_before_the_manifest_named_such_stops_is_partial_all_the_same(keys, line, tmp_path,
                                                                                     monkeypatch):
    """What the signed stop_summary says counts: a manifest without no_stop (signed by an earlier planner) does
    not make a bundle that cannot stop its train complete; a no_stop that disagrees with it is never signed."""
    import planner.bundle.container as container

    tables = _no_pattern_at(all_tables(line), "S2")
    monkeypatch.setattr(container, "no_stop_rows", lambda t: [])  # as an earlier planner signed it
    info = verify_bundle(_build(tables, tmp_path / "old", keys[0], "sawtooth").path, keys[1])
    assert not info.complete and info.no_stop[0]["station_id"] == "S2"
    monkeypatch.setattr(container, "no_stop_rows",
                        lambda t: [{"station_id": "S1", "origin": "S0", "adhesion_kmh_s": ["2.5"]}])
    with pytest.raises(BundleError, match="manifest no_stop does not list the stops"):
        _build(tables, tmp_path / "wrong", keys[0], "sawtooth")
