"""The command's end (``planner.cli._exit_now``): no interpreter teardown, but nothing a normal exit does is lost."""
from __future__ import annotations

import subprocess
import sys
import threading

import pytest

import planner.cli as cli


def _ended(monkeypatch, *threads: threading.Thread) -> list:
    """Replace the process's end and the atexit run by recorders; the list says what happened, in order. The
    process's threads are this one and ``threads`` (pytest's process may hold others, a pool's among them)."""
    seen: list = []
    monkeypatch.setattr("os._exit", lambda code: seen.append(("exit", code)))
    monkeypatch.setattr("atexit._run_exitfuncs", lambda: seen.append(("atexit",)))
    monkeypatch.setattr("threading.enumerate", lambda: [threading.current_thread(), *threads])
    return seen


@pytest.mark.parametrize("code, want", [(0, 0), (None, 0), (3, 3)])
def test_ends_at_once_with_the_code_after_the_exit_handlers(monkeypatch, code, want):
    seen = _ended(monkeypatch)
    cli._exit_now(SystemExit(code))
    assert seen == [("atexit",), ("exit", want)]


def test_a_running_thread_gets_the_normal_exit(monkeypatch):
    """A non-daemon thread still at work is waited for: the normal exit (SystemExit raised again)."""
    go = threading.Event()
    t = threading.Thread(target=go.wait, name="still-working")
    t.start()
    try:
        seen = _ended(monkeypatch, t)
        with pytest.raises(SystemExit) as e:
            cli._exit_now(SystemExit(0))
        assert e.value.code == 0 and seen == []
    finally:
        go.set()
        t.join()
    daemon = threading.Thread(target=go.wait, daemon=True)  # a daemon never holds a normal exit up either
    daemon.start()
    seen = _ended(monkeypatch, daemon)
    cli._exit_now(SystemExit(0))
    assert seen == [("atexit",), ("exit", 0)]


def test_a_message_exit_is_the_normal_one(monkeypatch):
    seen = _ended(monkeypatch)
    with pytest.raises(SystemExit):
        cli._exit_now(SystemExit("a message for stderr"))
    assert seen == []


def test_a_real_process_flushes_and_runs_its_exit_handlers():
    """In a real process (the console entry point): the command's output and what an exit handler writes both
    arrive, with the code."""
    prog = ("import atexit, sys\n"
            "atexit.register(lambda: print('handler ran'))\n"
            "sys.argv = ['planner', '--version']\n"
            "import planner.cli\n"
            "planner.cli.console()\n"
            "print('not reached')\n")
    r = subprocess.run([sys.executable, "-c", prog], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == [f"planner {__import__('planner').__version__}", "handler ran"]


def test_main_itself_ends_in_systemexit():
    """Tests and embedding programs call ``main`` in their own process: it raises, never ends the process."""
    with pytest.raises(SystemExit) as e:
        import sys as _sys

        argv, _sys.argv = _sys.argv, ["planner", "--version"]
        try:
            cli.main()
        finally:
            _sys.argv = argv
    assert e.value.code in (0, None)


def test_python_m_ends_with_the_commands_code(tmp_path):
    r = subprocess.run([sys.executable, "-m", "planner.cli", "validate", str(tmp_path / "missing")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and r.stderr.startswith("error:") and "Traceback" not in r.stderr
