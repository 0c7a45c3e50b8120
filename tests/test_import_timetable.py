"""Timetables from outside: clock times in CSV and TOML, and a railML 2.x ``<timetable>``."""
from __future__ import annotations

import json

import pandas as pd
import pytest

from importsrc import EXTRA_TOML, railml_text, rolling_stock, write_railml
from linedb import write_line_db

from planner.errors import SourceError
from planner.line.importers.csv import export_csv, import_csv
from planner.line.importers.railml import import_railml
from planner.line.importers.timetable import clock_seconds


@pytest.mark.parametrize("text, seconds", [
    ("05:02:25", 5 * 3600 + 2 * 60 + 25), ("5:02", 5 * 3600 + 120), ("25:10:00", 25 * 3600 + 600),
    ("00:00:00.5", 0.5), ("21600", 21600.0), (21600, 21600.0), (" 06:00 ", 21600.0)])
def test_clock_times(text, seconds):
    assert clock_seconds(text, "x") == seconds


@pytest.mark.parametrize("text", ["5h02", "05:60:00", "05:02:61", "-10", "nan", "06:00:00 pm"])
def test_bad_clock_times_are_one_line_naming_where(text):
    with pytest.raises(SourceError) as e:
        clock_seconds(text, "tt.csv line 4 column arrival_s")
    msg = str(e.value)
    assert msg.startswith("tt.csv line 4 column arrival_s: ") and "\n" not in msg


def _csv_with_times(tmp_path, arrival: str):
    write_line_db(tmp_path / "a")
    export_csv(tmp_path / "a", tmp_path / "csv")
    f = tmp_path / "csv" / "timetable.csv"
    lines = f.read_text().splitlines()
    head = [ln for ln in lines if not ln.startswith("#")][0].split(",")
    k = next(i for i, ln in enumerate(lines) if not ln.startswith("#") and ln.split(",")[head.index("seq")] == "1")
    cells = lines[k].split(",")
    cells[head.index("arrival_s")] = arrival
    lines[k] = ",".join(cells)
    f.write_text("\n".join(lines) + "\n")
    return k + 1, pd.read_parquet(tmp_path / "a" / "timetable.parquet")


def test_csv_timetable_takes_clock_times(tmp_path):
    _, before = _csv_with_times(tmp_path, "")
    row = before[before["seq"] == 1].iloc[0]
    want = float(row["arrival_s"])
    h, rem = divmod(int(want), 3600)
    _csv_with_times(tmp_path / "x", f"{h:02d}:{rem // 60:02d}:{rem % 60:02d}")
    import_csv(tmp_path / "x" / "csv", tmp_path / "b")
    after = pd.read_parquet(tmp_path / "b" / "timetable.parquet")
    assert after[after["seq"] == 1].iloc[0]["arrival_s"] == want


def test_csv_bad_clock_time_names_file_line_and_column(tmp_path):
    line_no, _ = _csv_with_times(tmp_path, "7:3O")
    with pytest.raises(SourceError, match=rf"^timetable.csv line {line_no} column arrival_s: '7:3O' is not a time"):
        import_csv(tmp_path / "csv", tmp_path / "b")


def test_toml_timetable_takes_clock_times_also_past_midnight(tmp_path):
    f, r, x = write_railml(tmp_path)
    base = EXTRA_TOML.replace('at = "D1"\n', "")
    # TOML's own local times (before 24:00) and strings (also past it)
    x.write_text(base.replace("departure_s = 21600.0", "departure_s = 06:00:00")
                 .replace("arrival_s = 21900.0", "arrival_s = 06:05:00"))
    import_railml(f, "L1", [r], tmp_path / "a", extra=x)
    tt = pd.read_parquet(tmp_path / "a" / "timetable.parquet").sort_values("seq")
    assert list(tt["departure_s"].fillna(-1)) == [21600.0, 21930.0, -1]
    x.write_text(base.replace("departure_s = 21600.0", 'departure_s = "24:05:00"')
                 .replace("arrival_s = 21900.0", 'arrival_s = "24:10"')
                 .replace("departure_s = 21930.0", 'departure_s = "24:10:30"')
                 .replace("arrival_s = 22200.0", 'arrival_s = "24:15:00"'))
    import_railml(f, "L1", [r], tmp_path / "b", extra=x)
    tt = pd.read_parquet(tmp_path / "b" / "timetable.parquet").sort_values("seq")
    assert list(tt["departure_s"].fillna(-1)) == [86700.0, 87030.0, -1]
    assert list(tt["arrival_s"].fillna(-1)) == [-1, 87000.0, 87300.0]
    x.write_text(base.replace("arrival_s = 21900.0", 'arrival_s = "6h05"'))
    with pytest.raises(SourceError, match=r"^extra.toml: \[\[timetable\]\] #2.arrival_s: '6h05' is not a time"):
        import_railml(f, "L1", [r], tmp_path / "c", extra=x)


TIMETABLE = """
 <timetable id="tt1">
  <categories><category id="cat_R" code="R" name="Regional"/></categories>
  <trainParts>
   <trainPart id="tp1" trainNumber="101" categoryRef="cat_R">
    <ocpsTT>
     <ocpTT ocpRef="X" sequence="1" ocpType="begin"><times scope="scheduled" departure="05:55:00"/></ocpTT>
     <ocpTT ocpRef="W" sequence="2" ocpType="stop">
      <times scope="published" arrival="06:00" departure="06:01"/>
      <times scope="scheduled" arrival="05:59:30" departure="06:00:00"/></ocpTT>
     <ocpTT ocpRef="M" sequence="3" ocpType="stop"><times scope="scheduled" arrival="06:04:00" departure="06:04:30"/>
      <stopDescription commercial="true"/></ocpTT>
     <ocpTT ocpRef="E" sequence="4" ocpType="end"><times scope="scheduled" arrival="06:08:00"/></ocpTT>
    </ocpsTT>
   </trainPart>
   <trainPart id="tp2" trainNumber="102" categoryRef="cat_R">
    <ocpsTT>
     <ocpTT ocpRef="E" sequence="1" ocpType="begin"><times scope="scheduled" departure="23:56:00"/></ocpTT>
     <ocpTT ocpRef="M" sequence="2" ocpType="pass"><times scope="scheduled" arrival="23:59:00" departure="23:59:00"/></ocpTT>
     <ocpTT ocpRef="W" sequence="3" ocpType="end"><times scope="scheduled" arrival="00:03:30"/></ocpTT>
    </ocpsTT>
   </trainPart>
  </trainParts>
 </timetable>
"""


def railml_with_timetable(timetable: str = TIMETABLE) -> str:
    return railml_text().replace("</railml>", timetable + "</railml>")


def test_railml_timetable_imported(tmp_path):
    f, r, x = write_railml(tmp_path, railml_with_timetable())
    x.write_text(EXTRA_TOML.replace('at = "D1"\n', "").split("[[timetable]]")[0])
    s = import_railml(f, "L1", [r], tmp_path / "out", extra=x)
    tt = pd.read_parquet(tmp_path / "out" / "timetable.parquet")
    got = [tuple(None if pd.isna(v) else v for v in row) for row in
           tt[["train_id", "train_type", "direction", "seq", "station_id", "arrival_s", "departure_s", "stops"]]
           .itertuples(index=False)]
    # by hand: X is no station of the line; 102 passes midnight (arrival at W the next day)
    assert got == [
        ("101", "EMU", "down", 0, "W", None, 21600.0, True),
        ("101", "EMU", "down", 1, "M", 21840.0, 21870.0, True),
        ("101", "EMU", "down", 2, "E", 22080.0, None, True),
        ("102", "EMU", "up", 0, "E", None, 86160.0, True),
        ("102", "EMU", "up", 1, "M", 86340.0, 86340.0, False),
        ("102", "EMU", "up", 2, "W", 86400.0 + 210.0, None, True),
    ]
    notes = " ".join(s.notes)
    assert "2 trains from 2 railML train parts" in notes and "X" in notes and "after midnight" in notes


def test_railml_unknown_category_with_two_train_types_names_the_fix(tmp_path):
    f, r, x = write_railml(tmp_path, railml_with_timetable())
    rs2 = dict(rolling_stock(), name="LOCO")
    (tmp_path / "loco.json").write_text(json.dumps(rs2))
    x.write_text(EXTRA_TOML.replace('at = "D1"\n', "").split("[[timetable]]")[0])
    with pytest.raises(SourceError, match=r"<trainPart id='tp1'> @categoryRef: category 'R' is not a train type "
                                          r"\(EMU, LOCO\); .*train_type = 'R'"):
        import_railml(f, "L1", [r, tmp_path / "loco.json"], tmp_path / "out", extra=x)
    x.write_text(x.read_text().replace("[rolling_stock.EMU]", '[rolling_stock.EMU]\ntrain_type = "R"'))
    import_railml(f, "L1", [r, tmp_path / "loco.json"], tmp_path / "out", extra=x)
    assert set(pd.read_parquet(tmp_path / "out" / "timetable.parquet")["train_type"]) == {"R"}
