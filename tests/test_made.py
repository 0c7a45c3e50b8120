"""Dataset files made once (planner.job.made): the previous run's record is read strictly, a file is reused only
with the digest recorded, and a group is written when any of its files is not."""
from __future__ import annotations

import hashlib
import json
import os

import pytest

from planner.job.made import made_once, previous

KEY = "a" * 64


def _run(root, made, run="r0001-0123456789"):
    """A published run ``run`` under ``root`` (``latest`` at it) whose manifest records ``made``, with one file."""
    f = root / run / "table_a" / "run_id=r0001-0123456789" / "run_date=2026-12-06" / "line=L" / "direction=down"
    f.mkdir(parents=True)
    (f / "part-0.parquet").write_bytes(b"previous bytes")
    (root / run / "manifest.json").write_text(json.dumps({"made": made}))
    os.symlink(run, root / "latest")
    return f / "part-0.parquet"


REL = "table_a/line=L/direction=down/part-0.parquet"
SHA = hashlib.sha256(b"previous bytes").hexdigest()


def test_a_record_names_only_dataset_files_with_digests(tmp_path):
    _run(tmp_path, {KEY: [[REL, SHA]]})
    assert previous(tmp_path, use_cache=True).made == {KEY: ((REL, SHA),)}
    assert previous(tmp_path, use_cache=False) is None  # --no-cache: nothing of an earlier run
    for bad in ([["../../etc/passwd", SHA]], [["/abs/part-0.parquet", SHA]], [[REL, "not a digest"]],
                [["table_a/line=L/../x/part-0.parquet", SHA]], "no list", [[REL]]):
        m = tmp_path / "r0001-0123456789" / "manifest.json"
        m.write_text(json.dumps({"made": {KEY: bad}}))
        assert previous(tmp_path, use_cache=True) is None, bad


def _write(stage, calls):
    def write():
        calls.append(1)
        p = stage / "table_a" / "line=L" / "direction=down" / "part-0.parquet"
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"previous bytes")
        return [p]
    return write


def test_a_file_with_its_digest_is_linked_and_an_altered_one_is_written(tmp_path):
    old = _run(tmp_path, {KEY: [[REL, SHA]]})
    prev = previous(tmp_path, use_cache=True)
    calls = []
    files, rec = made_once(KEY, prev, tmp_path / "stage", _write(tmp_path / "stage", calls))
    assert not calls and files[0].stat().st_ino == old.stat().st_ino and rec == [[REL, SHA]]
    old.unlink()
    old.write_bytes(b"previous bytez")  # altered after its run
    calls = []
    files, rec = made_once(KEY, prev, tmp_path / "stage2", _write(tmp_path / "stage2", calls))
    assert calls and files[0].read_bytes() == b"previous bytes" and rec == [[REL, SHA]]
    calls = []
    made_once("b" * 64, prev, tmp_path / "stage3", _write(tmp_path / "stage3", calls))
    assert calls  # a group the previous run did not make


def test_without_hard_links_the_file_is_copied(tmp_path, monkeypatch):
    old = _run(tmp_path, {KEY: [[REL, SHA]]})
    prev = previous(tmp_path, use_cache=True)

    def no_links(*_a):
        raise OSError(1, "Operation not permitted")

    monkeypatch.setattr(os, "link", no_links)
    calls = []
    files, _ = made_once(KEY, prev, tmp_path / "stage", _write(tmp_path / "stage", calls))
    assert not calls and files[0].read_bytes() == b"previous bytes"
    assert files[0].stat().st_ino != old.stat().st_ino


@pytest.mark.parametrize("missing", [True, False])
def test_a_missing_previous_file_means_the_group_is_written(tmp_path, missing):
    old = _run(tmp_path, {KEY: [[REL, SHA], ["table_b/line=L/direction=down/part-0.parquet", SHA]]})
    if not missing:  # the second file there too, with the same bytes: both linked
        b = old.parents[5] / "table_b" / old.relative_to(old.parents[4])
        b.parent.mkdir(parents=True)
        b.write_bytes(b"previous bytes")
    calls = []
    stage = tmp_path / "stage"
    files, _ = made_once(KEY, previous(tmp_path, use_cache=True), stage, _write(stage, calls))
    assert bool(calls) == missing
    assert len(files) == (1 if missing else 2)


def test_the_bundles_record_is_read_strictly():
    """The previous run's bundle inputs keys (bundle → steps' table → key): a name that is not a bundle file's, a
    table that is not a steps' table, or a key that is not a digest drops the whole record (no bundle takes
    anything from the previous run)."""
    from planner.job.bundle_reuse import recorded

    good = {"sample_down_E10.pdb": {"table_d": "a" * 64, "stop_samples": "c" * 64},
            "sample_up_E10.pdb": {"eval_points": "b" * 64}}
    assert recorded({"bundle_inputs": good}) == good
    for bad in ({"../sample_down_E10.pdb": {"table_d": "a" * 64}}, {"sample_down_E10.pdb": {"table_d": "A" * 64}},
                {"sample_sideways_E10.pdb": {"table_d": "a" * 64}}, {"sample_down_E10.pdb": {"table_d": 7}},
                {"sample_down_E10.pdb": {"restrictions": "a" * 64}}, {"sample_down_E10.pdb": {"../x": "a" * 64}},
                {"sample_down_E10.pdb": "a" * 64}, ["sample_down_E10.pdb"]):
        assert recorded({"bundle_inputs": bad}) == {}
    assert recorded({}) == {}


def test_a_bundle_takes_a_table_only_with_the_tables_it_is_checked_against():
    """Of the steps' tables whose inputs did not change, one checked against another (table (b)'s ratios against
    (a)'s, (d)'s evaluation points against eval_points) is taken from the previous bundle only when the other is
    taken too, or is decoded by the build anyway (eval_points): otherwise the check between the taken bytes and the
    ones encoded anew would be left out."""
    from planner.job.bundle_reuse import taken

    stops = {"stop_summary", "stop_samples"}
    # the everyday edit: a leg's tables (a) to (c) changed; (d) and the evaluation points did not
    assert taken({"eval_points", "table_d"} | stops) == {"eval_points", "table_d"} | stops
    # (d) without its evaluation points: encoded again, so that the check runs on both
    assert taken({"table_d"} | stops) == stops
    # (b) and (c) are checked against (a): neither is taken without it, and (a) not without both
    assert taken({"eval_points", "table_b", "table_c", "table_d"}) == {"eval_points", "table_d"}
    assert taken({"eval_points", "table_a", "table_b", "table_d"}) == {"eval_points", "table_d"}
    assert taken({"eval_points", "table_a", "table_b", "table_c"}) == {"eval_points", "table_a", "table_b",
                                                                         "table_c"}
    # eval_points is decoded by every build: taken whatever else changed, its checks run again
    assert taken({"eval_points"}) == {"eval_points"}
    assert taken(set()) == set()
