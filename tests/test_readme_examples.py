"""The README's "Try, after `make run`" commands pass on any date (issue 50): they ran on one day only.

The nightly job is run on the sample into a folder of its own (its day is fixed, 2026-11-30, and the
machine's date is whatever it is: in CI a later one), then each command of the README block is run as
written, with ``.venv/bin/planner`` as ``python -m planner.cli`` and ``/tmp/`` as the test's own folder.
"""
from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _examples() -> list[list[str]]:
    text = (ROOT / "README.md").read_text()
    block = text.split("Try, after `make run`:", 1)[1].split("```sh", 1)[1].split("```", 1)[0]
    joined = re.sub(r"\\\n\s*", " ", block)
    return [shlex.split(ln) for ln in joined.splitlines() if ln.strip().startswith(".venv/bin/planner")]


def test_the_readmes_examples_pass_after_a_run_whatever_the_date(tmp_path):
    for name in ("lines", "feeds", "jobs"):
        shutil.copytree(ROOT / name, tmp_path / name)
    run = subprocess.run([sys.executable, "-m", "planner.cli", "run", "jobs/nightly.toml", "--no-progress"],
                         cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    cmds = _examples()
    assert len(cmds) >= 3 and any(c[1:3] == ["bundle", "verify"] for c in cmds)
    for cmd in cmds:
        args = [a.replace("/tmp/", f"{tmp_path}/") for a in cmd[1:]]
        r = subprocess.run([sys.executable, "-m", "planner.cli", *args], cwd=tmp_path, capture_output=True,
                           text=True)
        assert r.returncode == 0, (cmd, r.stdout[-500:], r.stderr[-500:])
