"""Run publication: staging, atomic latest, pruning, stale staging, lock, cache."""
import os

import pyarrow as pa
import pytest

from planner.errors import InputError, JobError
from planner.job.publish import (
    Cache,
    clean_stale_staging,
    digest,
    job_lock,
    latest_run,
    list_runs,
    next_run_id,
    publish,
    staging_dir,
)


def _stage(root, n):
    rid = next_run_id(root, f"{n:040x}")
    st = staging_dir(root, rid)
    (st / "file.txt").write_text(f"run {n}")
    return rid, st


def test_publish_swaps_latest_and_keeps_last_n(tmp_path):
    ids = []
    for n in range(4):
        rid, st = _stage(tmp_path, n)
        publish(tmp_path, st, rid, keep=2)
        ids.append(rid)
        assert latest_run(tmp_path) == rid
        assert (tmp_path / "latest" / "file.txt").read_text() == f"run {n}"
    assert ids[0].startswith("r0001-") and ids[3].startswith("r0004-")
    assert list_runs(tmp_path) == ids[2:]
    assert os.readlink(tmp_path / "latest") == ids[3]  # relative: the output root can move


def test_failed_run_leaves_latest_and_is_cleaned(tmp_path):
    rid, st = _stage(tmp_path, 1)
    publish(tmp_path, st, rid, keep=3)
    rid2, st2 = _stage(tmp_path, 2)  # never published: a failure or SIGKILL
    assert latest_run(tmp_path) == rid
    assert next_run_id(tmp_path, "f" * 40).startswith("r0003-")  # staged ids are not reused
    assert clean_stale_staging(tmp_path) == [f".staging-{rid2}"]
    assert latest_run(tmp_path) == rid and (tmp_path / rid / "file.txt").is_file()


def test_lock_refuses_a_second_job(tmp_path):
    with job_lock(tmp_path):
        # flock locks belong to the open file description: a second open conflicts
        with pytest.raises(JobError, match="another planner job"):
            with job_lock(tmp_path):
                pass


def test_cache_counts_hits_and_misses(tmp_path):
    c = Cache(tmp_path)
    key = digest({"a": 1.5, "b": [1, 2]})
    assert key == digest({"b": [1, 2], "a": 1.5})  # key order does not matter
    assert key != digest({"a": 1.5000000001, "b": [1, 2]})
    assert c.get("t", key) is None
    c.put("t", key, pa.table({"x": [1.0]}))
    assert c.get("t", key).to_pydict() == {"x": [1.0]}
    assert (c.hits, c.misses) == (1, 1)


def test_an_atomic_write_makes_its_folders_and_a_file_in_the_way_fails_it_leaving_nothing(tmp_path):
    """The folder is made only when it is missing (the write tries the file first); a file where a folder
    must be is an error, and the write leaves no temporary file behind."""
    import planner.io.atomic as atomic

    atomic.write_bytes_atomic(tmp_path / "a" / "b" / "c.bin", b"deep")
    assert (tmp_path / "a" / "b" / "c.bin").read_bytes() == b"deep"
    atomic.write_bytes_atomic(tmp_path / "a" / "b" / "c.bin", b"again")  # the folder is there now
    assert (tmp_path / "a" / "b" / "c.bin").read_bytes() == b"again"
    (tmp_path / "f").write_bytes(b"a file")
    with pytest.raises(OSError):
        atomic.write_bytes_atomic(tmp_path / "f" / "x.bin", b"x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "f"]
    assert sorted(p.name for p in (tmp_path / "a" / "b").iterdir()) == ["c.bin"]


def test_staged_files_are_flushed_once_by_publish_before_the_rename(tmp_path, monkeypatch):
    """Inside deferred_fsync an atomic write does not flush; publish flushes every staged file, then renames."""
    import planner.io.atomic as atomic
    import planner.job.publish as pub

    events = []
    monkeypatch.setattr(atomic, "_fsync_file", lambda p: events.append(("fsync", os.path.basename(p))))
    real_rename = os.rename
    monkeypatch.setattr(pub.os, "rename", lambda a, b: (events.append(("rename", "")), real_rename(a, b)))
    rid = next_run_id(tmp_path, "a" * 40)
    st = staging_dir(tmp_path, rid)
    with atomic.deferred_fsync():
        atomic.write_bytes_atomic(st / "x.bin", b"x")
        atomic.write_bytes_atomic(st / "sub" / "y.bin", b"y")
    assert events == []  # nothing flushed one by one
    atomic.write_bytes_atomic(tmp_path / "outside.bin", b"z")  # outside the context: flushed at once
    assert events == [("fsync", next(iter(events))[1])] and events[0][1].startswith(".outside.bin.")
    events.clear()
    publish(tmp_path, st, rid, keep=2)
    assert sorted(e for e in events if e[0] == "fsync") == [("fsync", "x.bin"), ("fsync", "y.bin")]
    assert events[-1] == ("rename", "")  # every flush before the run becomes visible


def test_the_writer_thread_keeps_the_deferred_flush(tmp_path, monkeypatch):
    """A file written inside deferred_fsync, on a thread handed the context (the run's writer thread), is not
    flushed one by one; a file written outside it is. The bytes are the table's alone: the same in both."""
    from concurrent.futures import ThreadPoolExecutor

    import planner.io.atomic as atomic
    from planner.io.parquet import write_parquet_atomic

    t = pa.table({"x": [1.0, 2.0]})
    flushed = []
    monkeypatch.setattr(atomic, "_fsync_file", flushed.append)
    with atomic.deferred_fsync(), ThreadPoolExecutor(1) as pool:
        write_parquet_atomic(t, tmp_path / "here.parquet")
        pool.submit(atomic.in_this_context(write_parquet_atomic), t, tmp_path / "thread.parquet").result()
    write_parquet_atomic(t, tmp_path / "outside.parquet")
    assert flushed and all("outside" in str(f) for f in flushed)  # only the write outside the run flushed
    assert len({(tmp_path / f"{n}.parquet").read_bytes() for n in ("here", "thread", "outside")}) == 1


def test_a_published_run_puts_its_id_and_date_above_each_dataset(tmp_path):
    """place_in_run moves each dataset's line= folders under run_id=/run_date= (the files untouched), leaves the
    run's other folders alone; a hive reader sees the run's columns, and a file's path pairs with another run's
    once the run's folders are taken out."""
    import pyarrow.dataset as pds

    from planner.io.parquet import place_in_run, run_dataset_dir, without_run, write_partitioned

    stage = tmp_path / ".staging-r0002-0123456789"
    t = pa.table({"line": ["L", "L"], "direction": ["down", "up"], "train_type": ["T", "T"], "x": [1.0, 2.0]})
    files = write_partitioned(t, stage, "margins")
    before = {f.relative_to(stage).as_posix(): f.read_bytes() for f in files}
    (stage / "inputs" / "L").mkdir(parents=True)
    (stage / "inputs" / "L" / "line.parquet").write_bytes(b"copy")
    (stage / "report").mkdir()
    assert run_dataset_dir(stage, "margins") == stage / "margins"  # staged: no run folders yet
    assert place_in_run(stage, "r0002-0123456789", "2026-12-06") == ["margins"]
    after = {p.relative_to(stage).as_posix(): p.read_bytes() for p in (stage / "margins").rglob("*.parquet")}
    assert all(k.startswith("margins/run_id=r0002-0123456789/run_date=2026-12-06/line=L/") for k in after)
    assert {without_run(k): v for k, v in after.items()} == before  # moved, not rewritten
    assert (stage / "inputs" / "L" / "line.parquet").read_bytes() == b"copy"
    assert run_dataset_dir(stage, "margins") == stage / "margins" / "run_id=r0002-0123456789" / "run_date=2026-12-06"
    got = pds.dataset(stage / "margins", format="parquet", partitioning="hive").to_table().to_pydict()
    assert set(got["run_id"]) == {"r0002-0123456789"} and set(got["run_date"]) == {"2026-12-06"}
    assert sorted(got["x"]) == [1.0, 2.0]
    with pytest.raises(InputError, match="run id"):
        place_in_run(tmp_path / "other", "../r1", "2026-12-06")


def test_a_copy_into_a_full_output_root_names_the_destination_not_the_input(tmp_path):
    """shutil.copyfile's ENOSPC names its source as filename, its destination as filename2: the job's
    copy of the line database into the run blamed the input file for the output root's full disk."""
    import errno
    import shutil
    import subprocess

    from planner.job.publish import output_root_errors

    src = tmp_path / "lines" / "x.parquet"
    src.parent.mkdir()
    src.write_bytes(os.urandom(256 * 1024))
    root = tmp_path / "out"
    root.mkdir()
    mounted = os.geteuid() == 0 and subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(root)],
                                                   capture_output=True).returncode == 0
    try:
        with pytest.raises(JobError) as e, output_root_errors(root):
            if mounted:
                shutil.copyfile(src, root / "x.parquet")  # 256 KiB into 64 KiB
            else:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(src), None, str(root / "x.parquet"))
    finally:
        if mounted:
            subprocess.run(["umount", "-l", str(root)], capture_output=True)
    assert str(e.value).startswith(f"{root / 'x.parquet'}: no space left on device (output root {root}); free space")
    with pytest.raises(JobError, match=f"^{src}: permission denied; check that path"), output_root_errors(root):
        raise PermissionError(errno.EACCES, "Permission denied", str(src))  # an input: still named


def test_work_started_in_the_background_flushes_as_its_caller_would():
    """A worker does not share the job's context: work started with background() from inside deferred_fsync (the
    chart pages, the train graph's page, the bundles) defers its flush there too, on a local worker and in this
    process alike; from outside, it flushes as usual."""
    import planner.io.atomic as atomic
    from planner.io.parallel import background

    with atomic.deferred_fsync():
        inside = [background(atomic.deferring, (), n_jobs=n) for n in (2, 1)]
        assert [b.result() for b in inside] == [True, True]
    outside = [background(atomic.deferring, (), n_jobs=n) for n in (2, 1)]
    assert [b.result() for b in outside] == [False, False]
