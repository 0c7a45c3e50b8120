"""Bundles for the day: the signed manifest names the operating day, its window and the temporary
restrictions included; a temporary restriction without a beacon is a DB-fed ATS-P pattern with its window,
flagged for overwrites beside the line's own; verify refuses the bundle outside the day."""
from __future__ import annotations

from datetime import date
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from linedb import write_line_db
from planner.bundle.container import build_line
from planner.bundle.manifest import Release
from planner.bundle.verify import read_bundle, verify_bundle
from planner.errors import BundleError
from planner.job.day import day_line
from planner.line.daily import load_feed
from planner.line.loader import load_line
from planner.line.operating_day import operating_day, restrictions_in_force
from planner.bundle.manifest import BundleDay
from test_daily_feed import OK, TZ, write_feed

# R1 of test_daily_feed: 2026-11-30T01:00 to 2026-12-02T05:00 JST, by hand in UTC
R1_FROM = 1795968000  # 2026-11-29T16:00:00Z
R1_UNTIL = R1_FROM + (2 * 24 + 4) * 3600  # 2026-12-01T20:00:00Z
DAY_START = R1_FROM + 2 * 3600  # 2026-11-30T03:00 JST = 2026-11-29T18:00:00Z
DAY_END = DAY_START + 86400


def _build(tmp_path, key, version: int = 1, out: str = "b"):
    from planner.line.operating_day import DayInputs

    line = load_line(write_line_db(tmp_path / "tiny", nodes=None, edges=None))
    other = {**OK, "restriction_id": "UP-ONLY", "start_m": 3000.0, "end_m": 3100.0, "direction": "up"}
    feed = load_feed(write_feed(tmp_path / "feed", restrictions=[OK, other]), line, TZ)
    w = operating_day(date(2026, 11, 30), TZ, 3)
    assert (w.start_s, w.end_s) == (DAY_START, DAY_END)
    rs = restrictions_in_force(feed.restrictions, w)
    day = BundleDay("2026-11-30", TZ, w.start_s, w.end_s,
                    tuple((r.restriction_id, r.valid_from_s, r.valid_until_s) for r in rs))
    return build_line(day_line(line, DayInputs(w, rs, ())), tmp_path / out, key,
                      release=Release(version, DAY_START - 6 * 3600 + version), directions=["down"],
                      train_types=["EMU10"], day=day)[0]


@pytest.fixture
def built(tmp_path):
    key = Ed25519PrivateKey.generate()
    return _build(tmp_path, key), key.public_key()


def test_the_manifest_names_the_day_its_window_and_the_restrictions_included(built):
    info, _ = built
    # UP-ONLY is in force that day but not for this (down) bundle
    assert info.operating_day == {"day": "2026-11-30", "time_zone": TZ, "valid_from": "2026-11-29T18:00:00Z",
                                  "valid_until": "2026-11-30T18:00:00Z", "restrictions": ["R1"]}


def test_a_restriction_without_beacon_is_a_db_fed_pattern_with_its_window_and_overwrite_flags(built):
    info, pub = built
    t = read_bundle(info.path, pub, at=DAY_START, allow_dev=True).tables
    atsp = {r["restriction_id"]: r for r in t["atsp"].to_pylist()}
    r1 = atsp["T.R1"]
    assert (r1["valid_from_utc_s"], r1["valid_until_utc_s"]) == (R1_FROM, R1_UNTIL)
    # pattern start by hand: v_high = min(100, 110) km/h, 45 km/h, ATS-P 2.9 km/h/s -> (v1^2 - v2^2) / 2b before 1000 m
    v1, v2, b = 100 / 3.6, 45 / 3.6, 2.9 / 3.6
    assert r1["pattern_start_m"] == pytest.approx(1000.0 - (v1 ** 2 - v2 ** 2) / (2 * b))
    assert r1["telegram"].startswith("P045")
    # the line's own 80 km/h curve limit (row 0, 1200-1600 m) is fed at 1200 - (v1^2 - (80/3.6)^2) / 2b = 1028 m,
    # while R1's pattern (fed at 618 m) must be held until its tail clears 1400 + 200 m: it overwrites R1's
    rest = {r["restriction_id"]: r for r in t["restrictions"].to_pylist()}
    assert rest["T.R1"]["kind"] == "temporary" and rest["T.R1"]["overwrite_conflict"]
    assert rest["R0"]["overwrites"] == "T.R1" and rest["R0"]["valid_from_utc_s"] is None


def test_verify_refuses_the_bundle_outside_its_day(built):
    info, pub = built
    assert verify_bundle(info.path, pub, at=DAY_START, allow_dev=True).operating_day["day"] == "2026-11-30"
    assert verify_bundle(info.path, pub, at=DAY_END - 1, allow_dev=True)
    for at, when in ((DAY_END, "2026-11-30T18:00:00Z"), (DAY_END + 3600, "2026-11-30T19:00:00Z"),
                     (DAY_START - 1, "2026-11-29T17:59:59Z")):
        with pytest.raises(BundleError) as e:
            verify_bundle(info.path, pub, at=at, allow_dev=True)
        assert str(e.value).endswith(f"bundle is for operating day 2026-11-30 (2026-11-29T18:00:00Z to "
                                     f"2026-11-30T18:00:00Z), checked at {when}: outside its window, that day's "
                                     f"bundle is needed (refused)")


def test_an_at_without_offset_is_the_local_time_of_the_bundles_day(built):
    """`--at 2026-12-03T02:00` was taken as UTC: on a Tokyo line that is 11:00 local, another day's window."""
    info, pub = built
    assert verify_bundle(info.path, pub, at="2026-11-30T03:00", allow_dev=True)  # the day's first second, JST
    assert verify_bundle(info.path, pub, at="2026-12-01T02:59:59", allow_dev=True)  # its last
    for local in ("2026-11-30T02:59:59", "2026-12-01T03:00"):
        with pytest.raises(BundleError, match="outside its window"):
            verify_bundle(info.path, pub, at=local, allow_dev=True)
    assert verify_bundle(info.path, pub, at="2026-11-29T18:00:00Z", allow_dev=True)  # an offset is kept as given
    with pytest.raises(BundleError, match="outside its window"):
        verify_bundle(info.path, pub, at="2026-11-29T17:59:59+00:00", allow_dev=True)


def test_two_runs_day_bound_bundles_are_compared_whenever_the_comparison_runs(tmp_path):
    """A change report compares yesterday's bundle (outside its day by now) with tonight's (not yet in its day):
    by content, whatever the clock says, while a vehicle's check refuses both outside the window."""
    from cryptography.hazmat.primitives import serialization

    from planner.report.bundle_changes import bundle_changes
    from planner.report.changes import LineChanges

    key = Ed25519PrivateKey.generate()
    pem = key.public_key().public_bytes(serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo)
    old, new = (_build(tmp_path / n, key, v, "bundles") for n, v in (("old", 1), ("new", 2)))  # the next release, same content
    for info in (old, new):
        (Path(info.path).parent / "signing_key.pub.pem").write_bytes(pem)
    old, new = Path(old.path), Path(new.path)
    assert old.read_bytes() != new.read_bytes()
    for at in (DAY_START - 86400, DAY_END + 86400):  # a vehicle's check: refused outside the day
        with pytest.raises(BundleError, match="outside its window"):
            verify_bundle(old, key.public_key(), at=at, allow_dev=True)
    ch = LineChanges("tiny", "r0001", "r0002")
    bundle_changes(ch, old.parent.parent, new.parent.parent)
    assert old.name == "tiny_down_EMU10.pdb" and ch.rows == []  # compared (not "could not be compared") and the same content: no change
    raw = bytearray(new.read_bytes())
    raw[raw.find(b"timetable") + 600] ^= 1  # one bit of tonight's flipped: it fails its checks and says so
    new.write_bytes(bytes(raw))
    bundle_changes(ch, old.parent.parent, new.parent.parent)
    assert len(ch.rows) == 1 and "could not be compared" in ch.rows[0]["detail"]
