"""SIGKILL the nightly job's main process at random moments; count what it leaves behind.

    python tests/stress_kill.py [--kills 20] [--grace 3.0] [--seed 1]

Runs ``planner run`` on a copy of the sample job (its own output root in a temporary folder, ``--no-cache``
so every night computes), kills the main process with SIGKILL at a seeded random moment of the night, then
watches every process of its session (its workers, loky's resource tracker) until all are gone, and looks
for staging folders in the output root and for a traceback or warning on the run's stderr. Prints one line per kill and a summary; exits 1 when a process
outlived ``--grace`` seconds or a staging folder was left. A tool for contributors (README: "Stress runs"),
not part of the suite: it takes about ``kills`` × 8 s.
"""
from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


NOISE = ("Traceback", "Warning", "warnings.warn", "Exception in thread")
"""What the run's own lines never contain: a library's traceback or warning."""


def session_members(sid: int) -> list[int]:
    """Live (not zombie) processes whose session is ``sid``: a killed process's children keep it."""
    out = []
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            stat = (p / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if fields[0] != "Z" and int(fields[3]) == sid:
            out.append(int(p.name))
    return out


def job_file(tmp: Path) -> Path:
    text = (ROOT / "jobs" / "nightly.toml").read_text()
    text = text.replace('lines = ["lines/sample"]', f'lines = ["{ROOT / "lines" / "sample"}"]')
    text = text.replace('output_root = "outputs"', f'output_root = "{tmp / "out"}"')
    text = text.replace('feeds = ["feeds/sample"]', f'feeds = ["{ROOT / "feeds" / "sample"}"]')
    job = tmp / "job.toml"
    job.write_text(text)
    return job


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kills", type=int, default=20)
    ap.add_argument("--grace", type=float, default=3.0, help="seconds the processes may outlive the main one")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    late = left = noisy = 0
    with tempfile.TemporaryDirectory(prefix="planner-kill-") as t:
        tmp = Path(t)
        job = job_file(tmp)
        cmd = [sys.executable, "-m", "planner.cli", "run", str(job), "--no-cache"]
        t0 = time.monotonic()
        r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        night = time.monotonic() - t0
        if r.returncode != 0:
            print(f"the night itself failed (exit {r.returncode}): {r.stderr.strip()[-500:]}")
            return 1
        print(f"an unkilled night: {night:.1f} s; killing {a.kills} nights at random moments in it")
        k = tries = 0
        while k < a.kills and tries < 3 * a.kills:  # a night that ends before its kill is tried again
            tries += 1
            p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                 start_new_session=True)
            at = rng.uniform(0.3, night * 0.8)
            try:
                p.wait(timeout=at)
            except subprocess.TimeoutExpired:
                pass
            if p.poll() is not None:
                print(f"night ended before its kill at {at:.2f} s (exit {p.returncode}): tried again")
                continue
            os.kill(p.pid, signal.SIGKILL)
            p.wait()
            k += 1
            t_kill = time.monotonic()
            alive = session_members(p.pid)
            gone_after = 0.0
            while alive and time.monotonic() - t_kill < 30.0:
                time.sleep(0.05)  # a measurement of how long they live, not a race: the bound is --grace
                alive = session_members(p.pid)
                gone_after = time.monotonic() - t_kill
            stderr = p.stderr.read().decode(errors="replace").strip() if p.stderr else ""
            staged = sorted(q.name for q in (tmp / "out").glob(".staging-*"))
            over = gone_after > a.grace or alive
            late += bool(over)
            left += bool(staged)
            noisy += any(w in stderr for w in NOISE)
            print(f"kill {k:2d} at {at:5.2f} s: "
                  f"its processes gone after {gone_after:.2f} s{' (still alive: %s)' % alive if alive else ''}; "
                  f"staging left: {staged or 'none'}{'; stderr: ' + stderr[-200:] if stderr else ''}")
            for pid in alive:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
    print(f"{k} kills: processes alive after {a.grace:g} s in {late}, staging folders left in {left}, "
          f"a traceback or warning on stderr in {noisy}")
    return 1 if late or left or noisy or k < a.kills else 0


if __name__ == "__main__":
    sys.exit(main())
