"""The nightly job end to end on a tiny line: incremental, atomic, killable, same on Dask.

The tiny line (tests/linedb.py) has 2 interstations × 2 directions × 2 train
types = 8 units per step, and a short closed-loop sweep keeps it fast.
"""
from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pyarrow.dataset as ds
import pytest

from linedb import default_tables, write_line_db
from planner import load_line
from planner.errors import PlannerError
from planner.io.parquet import without_run
from planner.job.config import load_job
from planner.job.publish import latest_run, list_runs

UNIT_STEPS = ("tables", "stops", "closed_loop")
N_UNITS = 2 * 2 * 2  # interstations × directions × train types


def _job(tmp_path: Path, parallel: str = "n_jobs = 2") -> Path:
    (tmp_path / "jobs").mkdir(exist_ok=True)
    p = tmp_path / "jobs" / "job.toml"
    p.write_text(textwrap.dedent("""
        [job]
        lines = ["lines/tiny"]
        output_root = "out"
        keep_runs = 3
        [stops]
        adhesion_kmh_s = "2.5:3.5:0.5"
        [closed_loop]
        modes = ["nearest", "adaptive"]
        horizon_s = 6.0
        step_s = 3.0
        [bundles]
        allow_development_key = true
        [parallel]
    """) + parallel + "\n")
    return p


def _write_tiny(folder: Path, **overrides) -> None:
    # the tiny network lacks a stop node at B; conflicts have their own tests (test_network*.py)
    write_line_db(folder, **({"nodes": None, "edges": None} | overrides))


@pytest.fixture
def project(tmp_path):
    _write_tiny(tmp_path / "lines" / "tiny")
    return tmp_path


def _run(job_path: Path):
    from planner.job.pipeline import run_job

    return run_job(load_job(job_path), show_progress=False)


def _tree_digest(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder``; in a page (.html), the run's id (the folder's name, which every
    page names at its top) is read as ``RUN``, so pages of two runs compare by what they show."""
    return {
        p.relative_to(folder).as_posix():
            hashlib.sha256(p.read_bytes().replace(folder.name.encode(), b"RUN") if p.suffix == ".html"
                           else p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*")) if p.is_file()
    }


def _assert_same_but_run_id(run_a: Path, run_b: Path, skip: str = "", no_changes: bool = False) -> None:
    """Two published runs hold the same files, byte for byte, except the manifest and overview page
    (they name the run and its timings), the run's id on the graph and timetable pages, and each dataset's
    run_id= and run_date= folders (a file's bytes do not name its run). ``no_changes``: one run has no earlier run, so the
    ``changes`` dataset and the report's "what changed" section are left out of the comparison."""
    import re

    a, b = ({without_run(k): v for k, v in _tree_digest(run).items()} for run in (run_a, run_b))
    for run_page in ("manifest.json", "index.html"):
        a.pop(run_page, None), b.pop(run_page, None)
    for d, folder in ((a, run_a), (b, run_b)):  # the graph and the tables name their run under the title
        for k in [k for k in d if k.split("/")[0] in ("graph", "timetable") and k.endswith(".html")]:
            text = (folder / k).read_text().replace(folder.resolve().name, "<run id>")
            d[k] = hashlib.sha256(text.encode()).hexdigest()
    if no_changes:
        for d, folder in ((a, run_a), (b, run_b)):
            for k in [k for k in d if k.startswith("changes/")]:
                d.pop(k)
            for k in [k for k in d if k.startswith("report/") and k.endswith("_margins.html")]:
                text = (folder / k).read_text().replace(folder.name, "RUN")
                text = re.sub(r"<style>[^<]*</style><section class='changes'.*?</section>", "", text, flags=re.S)
                d[k] = hashlib.sha256(text.encode()).hexdigest()
    if skip:
        a = {k: v for k, v in a.items() if not k.startswith(skip)}
        b = {k: v for k, v in b.items() if not k.startswith(skip)}
    assert sorted(a) == sorted(b)
    for k in a:
        assert a[k] == b[k], k


def test_cold_run_publishes_everything_and_reads_back(project):
    s = _run(_job(project))
    out = project / "out"
    assert latest_run(out) == s.run_id and (out / "latest" / "manifest.json").is_file()
    for step in UNIT_STEPS:
        assert s.computed[step] == N_UNITS  # closed loop: all scenarios × modes of a unit in one batch
    assert sorted(s.bundles) == [f"tiny_{d}_{t}.pdb" for d in ("down", "up") for t in ("EMU10", "EMU6")]
    for name in ("table_a", "table_b", "eval_points", "stop_summary", "closed_loop", "margins"):
        t = ds.dataset(out / "latest" / name, format="parquet", partitioning="hive").to_table()
        assert t.num_rows > 0 and {"line", "direction", "train_type"} <= set(t.column_names), name
        assert t.num_rows == s.rows[name]
    duckdb = pytest.importorskip("duckdb")
    n = duckdb.sql(
        f"select count(*) from read_parquet('{out}/latest/table_a/**/*.parquet', hive_partitioning=true) "
        "where direction = 'down' and train_type = 'EMU10'").fetchall()[0][0]
    assert n == s.rows["table_a"] // 4
    assert list((out / "latest" / "report").glob("*.html"))
    # the README's examples for analysts run as written against this run
    import re

    text = (out / "latest" / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 4
    for code in blocks:
        exec(code.replace("outputs/", f"{out}/"), {})
    # every row of every dataset carries the run's id and date (issue 17), the date from the run's start
    import datetime
    import json

    manifest = json.loads((out / "latest" / "manifest.json").read_text())
    # which machine code ran: the kernels built at install (make test builds them)
    assert manifest["software"]["kernels"] == {"integrator": "aot", "stopping": "aot"}
    assert "kernels built at install" in (out / "latest" / "index.html").read_text()
    assert manifest["run_date"] == datetime.datetime.now(datetime.timezone.utc).date().isoformat() or \
        manifest["run_date"] == (datetime.datetime.now(datetime.timezone.utc).date()
                                 - datetime.timedelta(days=1)).isoformat()  # a run across midnight
    for name in s.rows:
        t = ds.dataset(out / "latest" / name, format="parquet", partitioning="hive").to_table(
            columns=["run_id", "run_date"]).to_pandas()
        assert (t.run_id == s.run_id).all() and (t.run_date.astype(str) == manifest["run_date"]).all(), name
    from planner.bundle.verify import verify_bundle
    from planner.bundle.signing import load_public_key

    pub = load_public_key(out / "latest" / "bundles" / "signing_key.pub.pem")
    for b in s.bundles:
        assert verify_bundle(out / "latest" / "bundles" / b, pub, allow_dev=True).train_type in ("EMU10", "EMU6")
    # no key configured: a development key, said so in every signed manifest and in the run manifest
    import json

    from planner.errors import BundleError

    with pytest.raises(BundleError, match="development key"):
        verify_bundle(out / "latest" / "bundles" / s.bundles[0], pub)
    rel = json.loads((out / "latest" / "manifest.json").read_text())["bundles_release"]
    info = verify_bundle(out / "latest" / "bundles" / s.bundles[0], pub, allow_dev=True)
    assert rel == {"version": info.bundle_version, "built_at": info.built_at, "expires": info.expires,
                   "key_kind": "development"}


def test_unchanged_rerun_computes_nothing(project, monkeypatch):
    # bundles carry their build time (issue 21): runs with the same SOURCE_DATE_EPOCH give the same bytes
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")  # 2026-01-01T00:00:00Z
    job = _job(project)
    first = _run(job)
    again = _run(job)
    assert again.up_to_date and again.run_id == first.run_id and again.computed == {}
    # Without the whole-run shortcut (latest removed), every unit still comes from the cache.
    os.unlink(project / "out" / "latest")
    third = _run(job)
    assert not third.up_to_date
    assert all(third.computed.get(step, 0) == 0 for step in UNIT_STEPS + ("margins", "conflicts"))
    assert third.reused["tables"] == N_UNITS
    a = _tree_digest(project / "out" / first.run_id)
    b = _tree_digest(project / "out" / third.run_id)
    for run_page in ("manifest.json", "index.html"):  # they name the run and its timings
        a.pop(run_page), b.pop(run_page)
    # byte-identical report, bundles and datasets from cache: a dataset names its run in its folders only
    assert any(k.startswith(f"margins/run_id={first.run_id}/run_date=") for k in a)
    assert any(k.startswith(f"margins/run_id={third.run_id}/run_date=") for k in b)
    assert {without_run(k): v for k, v in a.items()} == {without_run(k): v for k, v in b.items()}
    import pyarrow.parquet as pq

    assert "run_id" not in pq.read_schema(project / "out" / third.run_id / next(k for k in b if k.startswith("margins/"))).names
    got = pd.read_parquet(project / "out" / "latest" / "margins")  # a reader of the dataset sees the run's columns
    assert set(got["run_id"].astype(str)) == {third.run_id} and got["run_date"].nunique() == 1


def test_a_csv_round_trip_of_the_line_recomputes_nothing(project):
    """A planner who exports the line to CSV and imports it back unchanged gets the same bytes (the
    importers write the declared form), so the next run is the same run: nothing recomputed."""
    from planner.line.importers.csv import export_csv, import_csv

    tiny = project / "lines" / "tiny"
    export_csv(tiny, project / "csv")
    import_csv(project / "csv", tiny, force=True)  # the line in the form every importer writes
    job = _job(project)
    first = _run(job)
    before = _tree_digest(tiny)
    export_csv(tiny, project / "csv2")
    import_csv(project / "csv2", tiny, force=True)
    assert _tree_digest(tiny) == before
    again = _run(job)
    assert again.up_to_date and again.run_id == first.run_id and again.computed == {}


def test_one_edited_restriction_recomputes_only_its_interstation(project):
    job = _job(project)
    _run(job)
    # The 70 km/h "up" restriction at 4000-4200 m lies between C (up stop 4740) and B (up stop 2440):
    # only the up run C->B of each of the 2 train types can see it.
    old_line = load_line(project / "lines" / "tiny")
    _edit_restriction(project, 65.0)
    s = _run(job)
    assert s.computed["tables"] == 2 and s.reused["tables"] == N_UNITS - 2
    assert s.computed["stops"] == 2
    assert s.computed["closed_loop"] == 2
    _check_changes_name_the_restriction(project, old_line, load_line(project / "lines" / "tiny"))


def _made_files(run: Path, datasets=("eval_points", "table_a", "table_b", "table_c", "table_d", "stop_summary",
                                     "stop_samples", "closed_loop", "closed_loop_summary")) -> dict[str, Path]:
    return {without_run(p.relative_to(run).as_posix()): p for d in datasets for p in (run / d).rglob("*.parquet")}


def test_a_partition_written_in_parts_holds_the_rows_written_whole(project, monkeypatch):
    """The tables', stopping patterns' and closed loop's datasets written in parts of one interstation (two files a
    partition on the tiny line) hold the rows written in one part, in the same order (the stopping patterns' rows
    are sorted within a file: the same rows), and count alike: no part's file is another's."""
    import json

    import planner.job.steps as steps

    whole = project / "out" / _run(_job(project)).run_id
    job = project / "jobs" / "parts.toml"
    job.write_text((project / "jobs" / "job.toml").read_text().replace('output_root = "out"', 'output_root = "parts"'))
    monkeypatch.setattr(steps, "PART_UNITS", 1)
    parts = project / "parts" / _run(job).run_id
    names = ("eval_points", "table_a", "table_b", "table_c", "table_d", "stop_summary", "stop_samples",
             "closed_loop", "closed_loop_summary")
    for name in names:
        a, b = (sorted((run / name).rglob("*.parquet")) for run in (whole, parts))
        assert {p.name for p in a} == {"part-0.parquet"} and {p.name for p in b} == {"part-0.parquet", "part-1.parquet"}
        fa, fb = (pd.read_parquet(run / name).drop(columns=["run_id"]) for run in (whole, parts))
        if name.startswith("stop_"):
            fa, fb = (f.sort_values(list(f.columns), kind="stable").reset_index(drop=True) for f in (fa, fb))
        pd.testing.assert_frame_equal(fa, fb, obj=name)
    rows = [json.loads((run / "manifest.json").read_text())["rows"] for run in (whole, parts)]
    assert rows[0] == rows[1] and all(rows[0][n] for n in names)


def test_an_edit_reuses_the_files_of_the_partitions_it_did_not_touch(project):
    """The tables', stops' and closed loop's files of the partitions an edit did not touch are the previous run's
    files (the same inode: linked, not written again); those of the partitions it touched are new. A previous file
    that was altered after its run is not reused: its group is written again, to the bytes it had."""
    job = _job(project)
    first = project / "out" / _run(job).run_id
    before = _made_files(first)
    down = [k for k in before if "direction=down" in k]
    assert down and len(down) < len(before)
    bad = first / next(p for p in before.values() if "table_b" in p.parts and "direction=down" in p.parts) \
        .relative_to(first)
    good = bad.read_bytes()
    bad.unlink()  # a new file under the old name, as any later write makes it (the other run's link is kept)
    bad.write_bytes(good[:-8] + b"\0" * 8)
    facts = {p: p.stat().st_ino for p in (project / "out" / ".cache" / "closed_loop_facts").rglob("*.pce")}
    assert len(facts) == 4  # what the margins read of each closed-loop part (a direction and type each)
    _edit_restriction(project, 65.0)  # seen by the up runs C->B alone
    second = project / "out" / _run(job).run_id
    # the down parts' facts read back, not made again (stored anew); the up parts' made for their new runs
    again = {p: p.stat().st_ino for p in (project / "out" / ".cache" / "closed_loop_facts").rglob("*.pce")}
    assert {p: again.get(p) for p in facts} == facts and len(again) == 6
    after = _made_files(second)
    assert sorted(after) == sorted(before)
    bad_group = {k for k in before if k.split("/")[0] in ("eval_points", "table_a", "table_b", "table_c", "table_d")
                 and k.split("/", 1)[1] == without_run(bad.relative_to(first).as_posix()).split("/", 1)[1]}
    assert len(bad_group) == 5  # the files one write of a part of the tables makes
    for k, p in after.items():
        same = p.stat().st_ino == before[k].stat().st_ino
        if "direction=up" in k or k in bad_group:
            assert not same, k  # touched by the edit, or a file of its group no longer its digest: written
        else:
            assert same, k  # the previous run's file
    assert after[without_run(bad.relative_to(first).as_posix())].read_bytes() == good
    import json

    made = json.loads((second / "manifest.json").read_text())["made"]
    assert sorted(r for files in made.values() for r, _ in files) == sorted(after)


def test_damaged_facts_of_a_closed_loop_part_are_made_again_from_its_rows(project):
    """What the margins read of a closed-loop part an edit did not touch comes from its cache entry; an entry that
    fails its digest is made again from the part's rows: the run warns once, counting them, and its margins are
    those of a run that read nothing from the cache."""
    from planner.job.pipeline import run_job

    job = _job(project)
    _run(job)
    for p in (project / "out" / ".cache" / "closed_loop_facts").rglob("*.pce"):
        data = bytearray(p.read_bytes())
        data[-1] ^= 1  # one bit of the payload
        p.write_bytes(bytes(data))
    _edit_restriction(project, 65.0)  # the down parts' files are the previous run's: their facts are read
    s = _run(job)
    assert [w[:19] for w in s.warnings] == ["2 cache entries in "], s.warnings
    fresh = run_job(load_job(job), show_progress=False, use_cache=False)
    margins = [{k: v for k, v in _tree_digest(project / "out" / r).items() if k.startswith(("margins/", "margin_"))}
               for r in (s.run_id, fresh.run_id)]
    assert margins[0] and [{without_run(k): v for k, v in m.items()} for m in margins][0] == \
        {without_run(k): v for k, v in margins[1].items()}


def _resigned_with_other_bytes(path: Path, key_pem: Path, member: str) -> bytes:
    """The bundle at ``path`` signed again (with the run's key) with ``member`` in other bytes of the same table
    (snappy, not zstd): a bundle that verifies and whose ``member`` the nightly job's encoding never gives. Returns
    those bytes."""
    import io
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from planner.bundle import signing
    from planner.bundle.archive import pack, read_members
    from planner.bundle.manifest import canonical_json

    members, _ = read_members(path)
    buf = io.BytesIO()
    pq.write_table(pq.read_table(pa.BufferReader(members[member])), buf, compression="snappy", store_schema=False)
    other = members[member] = buf.getvalue()
    m = json.loads(members["manifest.json"])
    for e in m["files"]:
        if e["name"] == member:
            e["size"], e["sha256"] = len(other), hashlib.sha256(other).hexdigest()
    members["manifest.json"] = canonical_json(m)
    members["manifest.sig"] = signing.sign(signing.load_private_key(key_pem), members["manifest.json"])
    path.unlink()
    path.write_bytes(pack(members))
    return other


def _codec(parquet: bytes) -> str:
    import pyarrow as pa
    import pyarrow.parquet as pq

    return pq.ParquetFile(pa.BufferReader(parquet)).metadata.row_group(0).column(0).compression


def test_an_edit_signs_the_bundles_it_did_not_touch_with_their_previous_tables(project):
    """A bundle whose datasets an edit did not touch takes its steps' tables from the previous run's bundle, as
    they are there (only its line's own tables are made again, and its manifest signed anew); a bundle the edit
    touched encodes the tables it touched from the datasets and takes the others (its evaluation points), and a bundle
    whose previous bundle no longer verifies is built from the datasets."""
    import json

    from planner.bundle.archive import read_members
    from planner.bundle.verify import verify_bundle

    job = _job(project)
    first = project / "out" / _run(job).run_id
    key = project / "out" / ".dev-key" / "signing_key.pem"
    names = ("tiny_down_EMU6.pdb", "tiny_up_EMU6.pdb", "tiny_down_EMU10.pdb")
    before = {n: read_members(first / "bundles" / n)[0] for n in names}
    other = {n: _resigned_with_other_bytes(first / "bundles" / n, key, "table_c.parquet") for n in names[:2]}
    points = _resigned_with_other_bytes(first / "bundles" / names[1], key, "eval_points.parquet")
    (first / "bundles" / names[2]).write_bytes(b"not a bundle any more")
    _edit_restriction(project, 65.0)  # the up runs C->B alone
    second = project / "out" / _run(job).run_id
    pub = first / "bundles" / "signing_key.pub.pem"
    after = {n: read_members(second / "bundles" / n)[0] for n in names}
    for n in names:
        assert verify_bundle(second / "bundles" / n, pub.read_bytes(), allow_dev=True).complete
    assert after[names[0]]["table_c.parquet"] == other[names[0]]  # taken from the previous bundle, as it was there
    assert after[names[0]]["table_d.parquet"] == before[names[0]]["table_d.parquet"]
    assert after[names[0]]["manifest.json"] != before[names[0]]["manifest.json"]  # signed anew
    assert _codec(after[names[0]]["table_c.parquet"]) == "SNAPPY"
    assert _codec(after[names[1]]["table_c.parquet"]) == "ZSTD"  # the edit's: encoded from the datasets
    assert after[names[1]]["eval_points.parquet"] == points  # the edit did not touch them: taken as they were
    assert after[names[1]]["table_a.parquet"] != before[names[1]]["table_a.parquet"]  # the edit's rows
    assert after[names[2]]["table_c.parquet"] == before[names[2]]["table_c.parquet"]  # built again, the same
    keys = [json.loads((run / "manifest.json").read_text())["bundle_inputs"] for run in (first, second)]
    assert len(keys[0]) == 4 and sorted(keys[0]) == sorted(keys[1])
    assert {n for n in keys[0] if keys[0][n] == keys[1][n]} == {"tiny_down_EMU6.pdb", "tiny_down_EMU10.pdb"}
    edited = keys[0][names[1]], keys[1][names[1]]  # per table: the ones the edit touched have new keys
    assert {t for t in edited[0] if edited[0][t] == edited[1][t]} == {"eval_points"}


def _check_changes_name_the_restriction(project: Path, old_line, new_line) -> None:
    """The run's `changes` dataset and the report's top section name the edited restriction and the legs it slowed."""
    from planner.api import running_time

    ch = ds.dataset(project / "out" / "latest" / "changes", format="parquet", partitioning="hive").to_table().to_pandas()
    inputs = ch[ch.category == "line_table"]
    assert list(zip(inputs.subject, inputs.field, inputs.before, inputs.after)) == [("speed_limits", "limit_kmh", "70", "65")]
    cid = int(inputs.change_id.iloc[0])
    legs = ch[(ch.category == "leg") & (ch.field == "min_running_time_s")]
    # only up runs from C to B (or through it) can see a restriction at 4000-4200 m in the up direction
    assert len(legs) and set(legs.direction) == {"up"} and all(cid in list(c) for c in legs.caused_by)
    assert "run" not in ch.columns and set(ch.run_id) == {(project / "out" / "latest").resolve().name}
    for r in legs.itertuples():
        assert r.subject.startswith(f"{r.train_type} up C→") and r.origin == "C"  # structured columns to join on
        # by how much: the same as the simulator's minimum time C→B before and after, run independently here
        dest = r.destination
        assert r.subject.startswith(f"{r.train_type} up C→{dest}")
        want = (running_time(new_line, r.train_type, "C", dest).time_s
                - running_time(old_line, r.train_type, "C", dest).time_s)
        assert want > 0.5 and abs(r.delta - want) < 0.05, (r.subject, r.delta, want)
    html = (project / "out" / "latest" / "report" / "tiny_margins.html").read_text()
    top = html.index("What changed since the last run")
    assert top < html.index("impossible: scheduled below")  # a section at the top, before the headline cards
    assert "speed restriction 4000–4200 m up civil: limit_kmh 70 → 65 — affects" in html


def _edit_restriction(project: Path, limit_kmh: float) -> None:
    """Change the 70 km/h "up" restriction at 4000-4200 m (seen only by the up runs C->B)."""
    t = default_tables()
    sl = t["speed_limits"]
    sl.loc[sl["start_m"] == 4000.0, "limit_kmh"] = limit_kmh
    _write_tiny(project / "lines" / "tiny", speed_limits=sl)


def _failed_then_again(project: Path, monkeypatch, name: str):
    """A run after an edit with ``planner.job.pipeline.<name>`` failing: it raises and leaves ``latest`` (its files
    too) as the run before made it; then the same run without the failure, whose summary is returned (it cleans
    the failed staging folder and reuses what the failed run computed)."""
    import planner.job.pipeline as pl

    job = _job(project)
    first = _run(job)
    out = project / "out"
    before = _tree_digest(out / first.run_id)

    def boom(*a, **k):
        raise PlannerError(f"{name} failed on purpose")

    monkeypatch.setattr(pl, name, boom)
    _edit_restriction(project, 65.0)
    with pytest.raises(PlannerError, match="on purpose"):
        _run(job)
    assert latest_run(out) == first.run_id and list_runs(out) == [first.run_id]
    assert _tree_digest(out / first.run_id) == before
    monkeypatch.undo()
    s = _run(job)
    assert latest_run(out) == s.run_id and not [p for p in out.iterdir() if p.name.startswith(".staging")]
    return s


def test_failing_step_leaves_latest_untouched(project, monkeypatch):
    s = _failed_then_again(project, monkeypatch, "bundles_step")
    assert s.computed["tables"] == 0 and s.computed["stops"] == 0 and s.computed["closed_loop"] == 0


def test_sections_failing_while_the_tables_run_lets_them_finish_and_leaves_latest(project, monkeypatch):
    """The line's sections are planned while its tables and stops run on the workers: a failure there ends the run
    as any step's does, once the started units are in (cached: the next run computes none of them again)."""
    s = _failed_then_again(project, monkeypatch, "line_section_inputs")
    assert s.computed["tables"] == 0 and s.computed["stops"] == 0 and s.computed["closed_loop"] > 0


def test_sigkill_at_each_kind_of_moment_leaves_the_previous_run(project, tmp_path_factory, monkeypatch):
    """SIGKILL a run at deterministic points, each signalled by the run itself (no wall-clock race).

    After one edited restriction a run stores 13 units in the cache, in this order: tables 2, stops 2,
    closed loop 2, margin leg groups 3, margins 1, train graph 1, running-time tables 1, charts 1; its 14th
    kill point is the complete staged run just before publishing. Successive runs are killed at the 1st (mid
    tables), 3rd (first stop pattern), 5th (mid closed loop), 8th (mid margin legs), 10th (the margin report
    cached, bundles not yet written), 11th (the graph's trajectories), 12th (the running-time tables), 13th
    (the last chart) and 14th of those points; each resumes from what the killed ones cached. After every
    kill ``latest`` and the published run are untouched; the run that finally completes computes nothing and
    publishes exactly what an uninterrupted run from the same starting cache publishes.
    """
    import shutil

    from planner.job.units import KILL_ENV

    job = _job(project)
    first = _run(job)
    out = project / "out"
    before = _tree_digest(out / first.run_id)
    _edit_restriction(project, 65.0)
    # Reference: the same run, uninterrupted, in a copy of the project with the same cache and key.
    ref = tmp_path_factory.mktemp("ref")
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")  # the same build time as the killed runs below
    shutil.copytree(project / "lines", ref / "lines")
    for d in (".cache", ".dev-key"):
        shutil.copytree(out / d, ref / "out" / d)
    clean = _run(_job(ref))
    # the train graph's trajectories and its page's share are a unit each keyed by the whole line database (the
    # sample is one section): they change too
    # and of the speed-distance charts only the up leg's (202, C-A passing B): the down legs do not see it
    # of the margin report's 9 leg groups the 3 up groups from C (EMU10 C-B, EMU6 C-B and C-A): the others'
    # stretches (stop markers ± a train length) do not reach 4000 m or are down runs
    assert {k: v for k, v in clean.computed.items() if v} == {"tables": 2, "stops": 2, "closed_loop": 2,
                                                              "margins": 1, "margin_leg": 3, "graph": 2,
                                                              "charts": 1, "timetable": 1}

    # bundles carry their build time (issue 21): the killed runs and the reference share one
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).parent), SOURCE_DATE_EPOCH="1767225600")
    code = ("from planner.job.config import load_job; from planner.job.pipeline import run_job; "
            f"run_job(load_job({str(job)!r}), show_progress=False)")
    done = 0
    for point in (1, 3, 5, 8, 10, 11, 12, 13, 14):  # 11: after the graph unit, 14: before publishing
        p = subprocess.Popen([sys.executable, "-c", code], env=env | {KILL_ENV: str(point - done)},
                             start_new_session=True)
        rc = p.wait()
        try:
            os.killpg(p.pid, signal.SIGKILL)  # its joblib workers, if any outlived it
        except ProcessLookupError:
            pass
        assert rc == -signal.SIGKILL, f"run not killed at kill point {point} (exit code {rc})"
        done = point
        assert latest_run(out) == first.run_id and list_runs(out) == [first.run_id]
        assert _tree_digest(out / first.run_id) == before
    s = _run(job)
    assert latest_run(out) == s.run_id and not [p for p in out.iterdir() if p.name.startswith(".staging")]
    assert not any(s.computed.values())  # every unit came from what the killed runs cached
    _assert_same_but_run_id(out / s.run_id, ref / "out" / clean.run_id, no_changes=True)


def test_dask_backend_gives_the_same_datasets(project, tmp_path_factory):
    distributed = pytest.importorskip("dask.distributed")
    local = _run(_job(project))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        other = tmp_path_factory.mktemp("dask")
        _write_tiny(other / "lines" / "tiny")
        job = _job(other, f'backend = "dask"\nscheduler = "{cluster.scheduler_address}"')
        s = _run(job)
    # bundles are signed with each project's own development key
    _assert_same_but_run_id(project / "out" / local.run_id, other / "out" / s.run_id, skip="bundles/")


def test_a_new_signing_key_at_the_same_path_is_a_change(project):
    from planner.bundle.verify import verify_bundle
    from planner.bundle.signing import generate_keypair, load_public_key

    keys = project / "keys"
    generate_keypair(keys)
    job = _job(project)
    job.write_text(job.read_text().replace("[bundles]\n", '[bundles]\nsigning_key = "keys/signing_key.pem"\n'))
    first = _run(job)
    for f in keys.iterdir():
        f.unlink()
    _, pub = generate_keypair(keys)  # rotated: same path, other key
    s = _run(job)
    assert not s.up_to_date and s.run_id != first.run_id
    assert s.computed["tables"] == 0  # the key only changes the bundles
    b = project / "out" / "latest" / "bundles"
    assert (b / "signing_key.pub.pem").read_bytes() == pub.read_bytes()
    verify_bundle(b / s.bundles[0], load_public_key(pub))


def test_an_up_to_date_run_starts_no_workers_and_any_change_does(project, monkeypatch):
    """The cheap check made before the workers start agrees with the full one: true only when the latest
    run has exactly these inputs (line bytes, parameters, key, date) and its bundles need no renewal."""
    import planner.job.pipeline as pl
    from planner.io import parallel

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    job_path = _job(project)
    job, root = load_job(job_path), project / "out"

    def current() -> bool:
        return pl._probably_current(job, root, pl.resolve_run_date(job), 1767225600, True)

    assert not current()  # no run yet (and no development key)
    _run(job_path)
    assert current()
    assert not pl._probably_current(job, root, pl.resolve_run_date(job), 1767225600, False)  # --no-cache
    assert not pl._probably_current(job, root, "2000-01-01", 1767225600, True)  # another date
    assert not pl._probably_current(job, root, pl.resolve_run_date(job), 1767225600 + 20 * 86400, True)  # renewal
    started = []
    real = parallel.Background.__init__
    monkeypatch.setattr(parallel.Background, "__init__",
                        lambda self, fn, args, n_jobs, pool=None: (started.append(n_jobs),
                                                                   real(self, fn, args, n_jobs, pool))[1])
    assert _run(job_path).up_to_date and started == []  # nothing to do: no worker started
    _edit_restriction(project, 65.0)
    assert not current()
    s = _run(job_path)
    assert not s.up_to_date and started and all(n != 1 for n in started)
