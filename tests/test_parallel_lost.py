"""A lost Dask cluster ends the run with one line within the configured bound; loky workers die with the run.

Issue 21 (items 6, 7) and issue 19 (scheduler lost mid-run). The kills are
deterministic: a scheduler plugin (or a scheduler preload) acts on the first
task that goes to ``processing``, i.e. when the run has started a unit, before
the worker can finish it, never after a sleep.

Workers are started as ``dask worker`` processes (nanny and worker in one
process group of their own) so that SIGKILL takes both, as in the issue's
probe; LocalCluster's nannies live inside the test process and would restart
a killed worker. The scheduler is LocalCluster's (in this process, no
workers), or a ``dask scheduler`` process when the scheduler itself is killed.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

distributed = pytest.importorskip("dask.distributed")

from planner.io.parallel import ClusterLostError, backend  # noqa: E402

HANG_GUARD_S = 120.0
"""Only to turn a hang into a failure; the bound under test is LOST_S."""
LOST_S = 1.0


def start_worker(address: str) -> subprocess.Popen:
    """A nanny + worker pair in a process group of its own."""
    return subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1", "--nworkers", "1",
         "--no-dashboard", "--death-timeout", "30"],
        start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def kill_group(p: subprocess.Popen) -> None:
    try:
        os.killpg(p.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    p.wait()


class KillWorkersOnFirstTask(distributed.diagnostics.plugin.SchedulerPlugin):
    """On the first task sent to a worker: SIGKILL every worker's process group (nanny and worker)."""

    def __init__(self, scheduler):
        self.scheduler = scheduler
        self.fired = threading.Event()
        self.killed_at = None

    def transition(self, key, start, finish, *args, **kwargs):
        if finish == "processing" and not self.fired.is_set():
            for ws in list(self.scheduler.workers.values()):
                try:
                    os.killpg(os.getpgid(ws.pid), signal.SIGKILL)
                except ProcessLookupError:
                    pass
            self.killed_at = time.monotonic()
            self.fired.set()


@pytest.fixture
def cluster():
    """A LocalCluster scheduler with one external worker process, and the kill plugin installed."""
    with distributed.LocalCluster(n_workers=0, processes=True, dashboard_address=":0") as lc:
        worker = start_worker(lc.scheduler_address)
        try:
            with distributed.Client(lc) as c:
                c.wait_for_workers(1, timeout=HANG_GUARD_S)
            plugin = KillWorkersOnFirstTask(lc.scheduler)
            lc.scheduler.add_plugin(plugin, name="kill-workers")
            yield lc, plugin, worker
        finally:
            kill_group(worker)


def in_thread(fn, guard_s: float = HANG_GUARD_S):
    """Run ``fn`` in a thread; return (result or exception, seconds); a hang fails the test."""
    out = {}

    def target():
        try:
            out["value"] = fn()
        except BaseException as e:  # noqa: BLE001
            out["value"] = e

    t = threading.Thread(target=target, daemon=True)
    t0 = time.monotonic()
    t.start()
    t.join(guard_s)
    assert not t.is_alive(), f"still waiting after {guard_s} s"
    return out["value"], time.monotonic() - t0


def test_all_workers_killed_mid_step_is_a_one_line_error(cluster):
    lc, plugin, _ = cluster

    def run():
        with backend("dask", scheduler=lc.scheduler_address, lost_timeout_s=LOST_S) as pool:
            return list(pool.imap(time.sleep, [(0.01,)] * 6))

    err, _ = in_thread(run)
    assert plugin.fired.is_set()
    assert isinstance(err, ClusterLostError), err
    msg = str(err)
    assert "\n" not in msg
    assert f"no workers for {LOST_S:g} s ([parallel] dask_lost_timeout_s)" in msg
    assert "0 of 6 unit(s) of this step done" in msg
    print(f"\nworkers killed -> error after {time.monotonic() - plugin.killed_at:.2f} s (bound {LOST_S} s): {msg}")


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


def test_scheduler_killed_mid_step_is_a_one_line_error(tmp_path):
    """Issue 19: the scheduler lost mid-run was a FutureCancelledError traceback."""
    pre = tmp_path / "die_preload.py"
    pre.write_text(SCHEDULER_PRELOAD)
    sfile = tmp_path / "scheduler.json"
    sched = subprocess.Popen(
        [sys.executable, "-m", "distributed.cli.dask_scheduler", "--port", "0", "--no-dashboard",
         "--scheduler-file", str(sfile), "--preload", str(pre)],
        start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    worker = None
    try:
        with distributed.Client(scheduler_file=str(sfile), timeout=HANG_GUARD_S) as c:
            address = c.scheduler.address
            worker = start_worker(address)
            c.wait_for_workers(1, timeout=HANG_GUARD_S)

        def run():
            with backend("dask", scheduler=address, lost_timeout_s=LOST_S) as pool:
                return list(pool.imap(time.sleep, [(0.01,)] * 4))

        err, secs = in_thread(run)
        assert sched.wait(timeout=HANG_GUARD_S) == -signal.SIGKILL
        assert isinstance(err, ClusterLostError), err
        msg = str(err)
        assert "\n" not in msg and msg.startswith(f"dask cluster {address} lost: ")
        assert "no scheduler answer" in msg or "cancelled" in msg
        print(f"\nscheduler killed -> error, {secs:.2f} s after the step began (bound {LOST_S} s): {msg}")
    finally:
        kill_group(sched)
        if worker is not None:
            kill_group(worker)


# --- the whole nightly job on a tiny line ---------------------------------------------------------
def _project(tmp_path: Path, address: str) -> Path:
    from linedb import write_line_db

    write_line_db(tmp_path / "lines" / "tiny", nodes=None, edges=None)
    (tmp_path / "jobs").mkdir()
    job = tmp_path / "jobs" / "job.toml"
    job.write_text(textwrap.dedent(f"""
        [job]
        lines = ["lines/tiny"]
        train_types = ["EMU6"]
        output_root = "out"
        [stops]
        adhesion_kmh_s = "2.5:3.5:0.5"
        [closed_loop]
        modes = ["nearest"]
        horizon_s = 6.0
        step_s = 3.0
        [bundles]
        allow_development_key = true
        [parallel]
        backend = "dask"
        scheduler = "{address}"
        dask_lost_timeout_s = {LOST_S}
    """))
    return job


@pytest.mark.slow
def test_nightly_job_with_every_worker_killed_fails_fast_frees_the_lock_and_the_next_run_succeeds(cluster, tmp_path):
    """Slow (a whole run of the tiny line for one train type after the failed one; minutes on a loaded machine)."""
    import fcntl

    from planner.job.config import load_job
    from planner.job.pipeline import run_job
    from planner.job.publish import latest_run

    lc, plugin, _ = cluster
    job = load_job(_project(tmp_path, lc.scheduler_address))
    err, _ = in_thread(lambda: run_job(job, show_progress=False))
    took = time.monotonic() - plugin.killed_at
    print(f"\nnightly job: error {took:.2f} s after the kill (bound {LOST_S} s): {err}")
    assert isinstance(err, ClusterLostError) and "\n" not in str(err), err
    assert "of this step done" in str(err)
    out = tmp_path / "out"
    assert latest_run(out) is None  # nothing published
    fd = os.open(out / ".lock", os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # raises BlockingIOError if still held
        fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
    # a new worker, the same job: it runs to the end and publishes
    lc.scheduler.remove_plugin(name="kill-workers")
    worker = start_worker(lc.scheduler_address)
    try:
        with distributed.Client(lc) as c:
            c.wait_for_workers(1, timeout=HANG_GUARD_S)
        s, secs = in_thread(lambda: run_job(job, show_progress=False), guard_s=900.0)  # a whole run
        assert not isinstance(s, BaseException), s
        assert latest_run(out) == s.run_id
    finally:
        kill_group(worker)
    print(f"\nnightly job: error {took:.2f} s after the kill (bound {LOST_S} s): {err}; lock free; "
          f"next run {s.run_id} published in {secs:.0f} s, computed {s.computed}, reused {s.reused}")


# --- local backend: loky workers end with the main process ----------------------------------------
LOCAL_CHILD = textwrap.dedent("""
    import os, sys, time
    from pathlib import Path
    import planner.job.pipeline as pipeline
    from planner.job.config import load_job

    marks = Path(sys.argv[2])

    def blocking_unit(*args):  # defined in __main__: pickled by value into the loky workers
        (marks / f"{os.getpid()}.started").write_text("")
        time.sleep(600)

    pipeline._tables_unit = blocking_unit
    pipeline.run_job(load_job(sys.argv[1]), show_progress=False)
""")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] != "Z"
    except (OSError, IndexError):
        return False


def test_loky_workers_end_when_the_main_process_is_killed(tmp_path):
    import fcntl

    from linedb import write_line_db

    write_line_db(tmp_path / "lines" / "tiny", nodes=None, edges=None)
    (tmp_path / "jobs").mkdir()
    job = tmp_path / "jobs" / "job.toml"
    job.write_text('[job]\nlines = ["lines/tiny"]\noutput_root = "out"\n[bundles]\nallow_development_key = true\n'
                   '[parallel]\nn_jobs = 2\n')
    marks = tmp_path / "marks"
    marks.mkdir()
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).parent))
    main = subprocess.Popen([sys.executable, "-c", LOCAL_CHILD, str(job), str(marks)], env=env,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + HANG_GUARD_S
        while len(list(marks.glob("*.started"))) < 2 and main.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)  # waiting for the signal that both workers started a unit, not racing it
        workers = [int(p.name.split(".")[0]) for p in marks.glob("*.started")]
        assert len(workers) == 2 and all(_alive(w) for w in workers), (workers, main.poll())
        main.send_signal(signal.SIGKILL)
        main.wait()
        # the lock dies with the main process (workers do not hold its descriptor)
        fd = os.open(tmp_path / "out" / ".lock", os.O_RDWR)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(fd)
        t0 = time.monotonic()
        while any(_alive(w) for w in workers) and time.monotonic() - t0 < 30.0:
            time.sleep(0.1)
        assert not any(_alive(w) for w in workers), "loky workers outlived the killed main process"
        print(f"\nloky workers gone {time.monotonic() - t0:.2f} s after SIGKILL of the main process")
    finally:
        try:
            os.killpg(main.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def test_lokys_worker_renewal_warning_is_filtered_and_only_it():
    """In a process of its own (pytest sets its own warning filters around each test)."""
    code = textwrap.dedent("""
        import warnings
        import planner.io.parallel  # installs the filter
        mod = "joblib.externals.loky.process_executor"
        renewed = ("A worker stopped while some jobs were given to the executor. This can be caused by a too "
                   "short worker timeout or by a memory leak.")
        warnings.warn_explicit(renewed, UserWarning, "process_executor.py", 787, module=mod)
        warnings.warn_explicit("some other loky warning", UserWarning, "process_executor.py", 790, module=mod)
        warnings.warn_explicit(renewed, UserWarning, "elsewhere.py", 1, module="someone.else")
    """)
    r = subprocess.run([sys.executable, "-W", "default", "-c", code], capture_output=True, text=True,
                       timeout=HANG_GUARD_S)
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if "UserWarning" in ln]
    assert len(lines) == 2, r.stderr
    assert lines[0].startswith("process_executor.py:790") and "some other loky warning" in lines[0]
    assert lines[1].startswith("elsewhere.py:1") and "A worker stopped" in lines[1]


ORPHAN = textwrap.dedent("""
    import sys, threading
    from planner.io.parallel import _exit_with_parent

    _exit_with_parent(int(sys.argv[1]))  # as loky's initializer is called, with the main process's id
    threading.Event().wait()  # a worker waiting for a task
""")


@pytest.mark.parametrize("held", [False, True])
def test_a_worker_whose_main_process_is_gone_ends_and_cleans_the_staging(tmp_path, held):
    """The main process's id is given to the worker, not read by it: a worker whose main process was killed
    while it was still starting read init's id as its parent's and lived on. On its way out it removes the
    output root's staging folders, unless a job holds the root's lock (that job cleans them itself)."""
    import fcntl

    from planner.io.parallel import OUTPUT_ROOT_ENV

    root = tmp_path / "out"
    (root / ".staging-r0003-0123456789").mkdir(parents=True)
    (root / ".staging-r0003-0123456789" / "half.parquet").write_bytes(b"x")
    (root / "r0002-0123456789").mkdir()  # a published run: never touched
    fd = os.open(root / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        if held:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        gone = os.getpid() + 10**6  # no process has this id: the main process is already gone
        env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]),
                   **{OUTPUT_ROOT_ENV: str(root)})
        r = subprocess.run([sys.executable, "-c", ORPHAN, str(gone)], env=env, capture_output=True, text=True,
                           timeout=HANG_GUARD_S)
    finally:
        os.close(fd)
    assert r.returncode == 1 and r.stderr == ""
    assert (root / "r0002-0123456789").is_dir()
    assert (root / ".staging-r0003-0123456789").exists() == held
