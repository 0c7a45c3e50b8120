"""An environment fault ends ``planner run`` with exactly one line on stderr (issue 32, item 2).

The whole stderr of the real command (a subprocess) is captured, so anything a library prints
besides the planner's line fails the test: a lost Dask scheduler made the ``distributed`` client log
its failed reconnect and three chained tracebacks; a full disk added joblib's two-line warning that
the step's remaining tasks were cancelled.

Both faults are set off by the run itself, never by a timer: the scheduler kills itself when the
first unit goes to a worker (a scheduler preload); the disk is full before the run starts (the
signing key already in place), so the first step's first result cannot be stored while the
workers hold the others.
"""
from __future__ import annotations

import contextlib
import errno
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from linedb import write_line_db

ROOT = Path(__file__).resolve().parents[1]
HANG_GUARD_S = 300.0
"""Only to turn a hang into a failure."""


def _job(project: Path, output_root: Path, parallel: str) -> Path:
    write_line_db(project / "lines" / "tiny", nodes=None, edges=None)
    job = project / "job.toml"
    job.write_text(textwrap.dedent(f"""
        [job]
        lines = ["lines/tiny"]
        train_types = ["EMU10"]
        output_root = "{output_root}"
        [tables]
        ratios = "1.0:0.7:0.1"
        ds_m = 5.0
        [stops]
        adhesion_kmh_s = "3.0:3.0:0.5"
        [closed_loop]
        modes = ["nearest"]
        horizon_s = 2.0
        step_s = 2.0
        scenarios = [{{name = "nominal"}}]
        [bundles]
        allow_development_key = true
    """) + textwrap.dedent(parallel))
    return job


MAIN = textwrap.dedent("""
    import gc, sys
    from planner.cli import main

    try:
        main()
    except SystemExit as e:
        code = e.code
    # what a longer process does at some moment: collect what the failed run left behind, its error
    # dropped (a joblib generator abandoned with tasks in hand warned when collected; a short run may
    # exit before a collection, and then the warning comes or not with the interpreter's teardown)
    gc.collect()
    sys.exit(code)
""")


def _planner_run(job: Path, *, before: str = "") -> tuple[int, str]:
    """``planner run JOB --no-progress`` in a fresh interpreter, after the code ``before``: (exit code,
    the whole stderr)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", before + MAIN, "run", str(job), "--no-progress"], env=env,
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=HANG_GUARD_S)
    return r.returncode, r.stderr


def _the_one_line(code: int, err: str, *needles: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 1 and len(lines) == 1, f"exit {code}, stderr:\n{err}"
    assert lines[0].startswith("error: ") and err == lines[0] + "\n", err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


# --- a lost Dask scheduler -----------------------------------------------------------------------
SCHEDULER_PRELOAD = textwrap.dedent("""
    import os, signal
    from distributed.diagnostics.plugin import SchedulerPlugin

    class Die(SchedulerPlugin):
        def transition(self, key, start, finish, *args, **kwargs):
            if finish == "processing":
                os.kill(os.getpid(), signal.SIGKILL)  # the scheduler dies as the first unit starts

    def dask_setup(scheduler):
        scheduler.add_plugin(Die(), name="die")
""")


def _kill_group(p: subprocess.Popen) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(p.pid, signal.SIGKILL)
    p.wait()


def test_a_lost_dask_scheduler_is_one_line_on_stderr(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    pre = tmp_path / "die_preload.py"
    pre.write_text(SCHEDULER_PRELOAD)
    sfile = tmp_path / "scheduler.json"
    quiet = dict(start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    sched = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                              "--port", "0", "--no-dashboard", "--scheduler-file", str(sfile), "--preload", str(pre)],
                             **quiet)
    worker = None
    try:
        with distributed.Client(scheduler_file=str(sfile), timeout=HANG_GUARD_S) as c:  # waits for the file
            address = c.scheduler.address
            worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--host",
                                       "127.0.0.1", "--nthreads", "1", "--no-dashboard", "--death-timeout", "30"],
                                      **quiet)
            c.wait_for_workers(1, timeout=HANG_GUARD_S)
        job = _job(tmp_path, tmp_path / "out", f"""
            [parallel]
            backend = "dask"
            scheduler = "{address}"
            dask_lost_timeout_s = 2.0
        """)
        code, err = _planner_run(job)
        assert sched.wait(timeout=HANG_GUARD_S) == -signal.SIGKILL  # the fault happened, during the run
        line = _the_one_line(code, err, f"dask cluster {address} lost: ", "check the cluster, then run again")
        assert not list((tmp_path / "out").glob(".staging-*"))  # the failed run removed what it had staged
        print(f"\nlost scheduler, the whole stderr: {line}")
    finally:
        _kill_group(sched)
        if worker is not None:
            _kill_group(worker)


def test_the_distributed_loggers_are_quiet_only_inside_the_dask_backend():
    """The levels go back as they were (a script that uses the planner and dask keeps its logging)."""
    import logging

    from planner.io.parallel import quiet_loggers

    pytest.importorskip("distributed")
    client, top = logging.getLogger("distributed.client"), logging.getLogger("distributed")
    before = client.level, top.level
    with quiet_loggers("distributed"):
        assert not client.isEnabledFor(logging.CRITICAL)
        assert not logging.getLogger("distributed.made_meanwhile").isEnabledFor(logging.CRITICAL)
    assert (client.level, top.level) == before


# --- a full disk ---------------------------------------------------------------------------------
@contextlib.contextmanager
def _full_tmpfs(path: Path):
    """A 1 MiB tmpfs at ``path`` (False where it cannot be mounted: not root)."""
    path.mkdir(parents=True)
    if os.geteuid() != 0 or not shutil.which("mount"):
        yield False
        return
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(path)], capture_output=True)
    if r.returncode != 0:
        yield False
        return
    try:
        yield True
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


def _fill(folder: Path) -> None:
    """Write zeros into ``folder`` until its file system says it is full."""
    with open(folder / "filler", "wb", buffering=0) as f:
        block = b"\0" * 65536
        while True:
            try:
                f.write(block)
            except OSError as e:
                assert e.errno == errno.ENOSPC, e
                break
        while True:  # the last, partial block
            try:
                f.write(b"\0" * 512)
            except OSError:
                break


SIMULATED_FULL = textwrap.dedent("""
    import errno, os
    from planner.job.cache import Cache

    def full(self, kind, key, obj):  # storing a result fails as on a full disk
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path(kind, key)))

    Cache.put = full
""")


HOLD_UNITS = textwrap.dedent("""
    import threading
    import planner.job.pipeline as pipeline

    _tables_unit = pipeline._tables_unit

    def held_tables_unit(line, tt, o, d, *rest):  # in __main__: pickled by value to the workers
        if (o, d) != ("A", "B"):  # every unit but the first waits: the workers hold them when the
            threading.Event().wait()  # first result cannot be stored (the run ends them)
        return _tables_unit(line, tt, o, d, *rest)

    pipeline._tables_unit = held_tables_unit
""")


def test_a_full_disk_is_one_line_on_stderr(tmp_path):
    from planner.bundle.signing import generate_keypair

    root = tmp_path / "out"
    with _full_tmpfs(root) as mounted:
        job = _job(tmp_path, root, """
            [parallel]
            n_jobs = 2
        """)
        generate_keypair(root / ".dev-key")  # so the first thing the run cannot write is a step's result
        if mounted:
            _fill(root)
        code, err = _planner_run(job, before=("" if mounted else SIMULATED_FULL) + HOLD_UNITS)
        line = _the_one_line(code, err, "no space left on device", f"(output root {root})",
                             "free space there or set [job] output_root to a larger disk")
        # the first entry of the work cache written (the line's sections, in the job process, or the first
        # step's first result, the workers holding the others): whichever comes first, it is named
        assert f"{root}/.cache/sections/" in line or f"{root}/.cache/tables/" in line
        print(f"\nfull disk ({'tmpfs 1m' if mounted else 'simulated ENOSPC'}), the whole stderr: {line}")


def _first_or_held(i: int) -> int:
    if i:
        import threading

        threading.Event().wait()  # held: the pool's abort ends the worker
    return i


def test_a_pool_left_with_tasks_in_hand_closes_without_a_warning():
    """The consumer stops after the first result (a failed run) while the workers hold the rest: closing
    the pool's generator aborts them quietly (joblib warned that the tasks were cancelled)."""
    import warnings

    from planner.io.parallel import backend

    with warnings.catch_warnings(record=True) as seen, backend("local", n_jobs=2) as pool:
        warnings.simplefilter("always")
        gen = pool.imap(_first_or_held, [(i,) for i in range(6)])
        assert next(gen) == 0
        gen.close()
    assert [str(w.message) for w in seen] == []


BUNDLES_FULL = textwrap.dedent("""
    import errno, os
    from planner.bundle import container

    def full(path, data):  # the disk fills as the first bundle is written
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    container.write_atomic = full
""")


def test_a_full_disk_at_the_bundles_names_the_output_root_not_a_cli_option(tmp_path):
    """The bundle step said "check --out", an option of `planner bundle build` that `planner run` does not have."""
    root = tmp_path / "out"
    job = _job(tmp_path, root, """
        [parallel]
        n_jobs = 1
    """)  # one job: the bundles are built in this process, where the patch is
    code, err = _planner_run(job, before=BUNDLES_FULL)
    line = _the_one_line(code, err, "no space left on device", f"(output root {root})",
                         "free space there or set [job] output_root to a larger disk", "(nothing was published)")
    assert "/bundles/tiny_down_EMU10.pdb:" in line and "--out" not in line


KILLED_WORKER = textwrap.dedent("""
    import planner.job.pipeline as pipeline

    def killed_tables_unit(*args):  # in __main__: pickled by value to the workers
        import os, signal
        os.kill(os.getpid(), signal.SIGKILL)  # as the kernel's out-of-memory killer does

    pipeline._tables_unit = killed_tables_unit
""")


def test_a_worker_killed_under_a_unit_is_one_line_on_stderr(tmp_path):
    """loky's TerminatedWorkerError was a traceback and four lines of text."""
    job = _job(tmp_path, tmp_path / "out", """
        [parallel]
        n_jobs = 2
    """)
    code, err = _planner_run(job, before=KILLED_WORKER)
    # the tiny line's 4 tables units share one pass of the workers with its 4 stopping-pattern units
    line = _the_one_line(code, err, "a local worker process died under a task (exit code {SIGKILL(-9)",
                         "of 8 task(s) done", "[parallel] n_jobs")
    # loky may report the sibling worker it terminated with the killed one: every exit code named is SIGKILL's
    import re

    assert re.search(r"\(exit code \{SIGKILL\(-9\)(, SIGKILL\(-9\))*\}: ", line), line
    assert not list((tmp_path / "out").glob(".staging-*"))  # the failed run removed what it had staged
    print(f"\nworker killed, the whole stderr: {line}")


def _kills_its_worker(i: int) -> int:
    if i == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    return i


def test_map_tasks_turns_a_killed_worker_into_one_error():
    from planner.io.parallel import WorkerLostError, map_tasks

    with pytest.raises(WorkerLostError, match=r"exit code \{SIGKILL\(-9\)\}.* of 3 task\(s\) done") as e:
        map_tasks(_kills_its_worker, [(i,) for i in range(3)], n_jobs=2)
    assert "\n" not in str(e.value)


MANAGER_THREAD = textwrap.dedent("""
    import sys, threading, types
    import planner.io.parallel  # installs the hook
    from joblib.externals.loky.process_executor import _ExecutorManagerThread

    class Manager(_ExecutorManagerThread):  # loky's thread class, failing as loky's race makes it fail
        def __init__(self, shutdown):
            threading.Thread.__init__(self, name="manager")
            self.executor_flags = types.SimpleNamespace(shutdown=shutdown)

        def run(self):
            raise KeyError(7)  # pending_work_items[work_id], the task gone with the shutdown

    t = Manager(sys.argv[1] == "shutdown")
    t.start()
    t.join()
""")


@pytest.mark.parametrize("state", ["shutdown", "running"])
def test_lokys_manager_thread_failing_in_a_shutdown_prints_nothing_and_only_then(state):
    """A run that failed closes its generators, joblib shuts loky's executor down, and loky's manager thread
    could print a KeyError traceback after the run's one line; an executor not shutting down still shows it."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", MANAGER_THREAD, state], env=env, capture_output=True, text=True,
                       timeout=HANG_GUARD_S)
    assert r.returncode == 0
    if state == "shutdown":
        assert r.stderr == ""
    else:
        assert "Exception in thread manager" in r.stderr and "KeyError: 7" in r.stderr
