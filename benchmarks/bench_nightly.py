"""The whole nightly job on the sample line, cold (empty cache) and warm (nothing changed).

Targets (issue 8): cold at most 120 s, warm at most 5 s on the 2-core machine.
Runs in a temporary copy of the project so the real outputs/ is untouched.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        proj = Path(tmp)
        shutil.copytree(ROOT / "lines" / "sample", proj / "lines" / "sample")
        shutil.copytree(ROOT / "jobs", proj / "jobs")
        for label in ("cold", "warm"):
            t0 = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "planner.cli", "run", "jobs/nightly.toml", "--no-progress"],
                               cwd=proj, capture_output=True, text=True)
            wall = time.perf_counter() - t0
            if r.returncode != 0:
                print(r.stdout, r.stderr)
                raise SystemExit(f"{label} run failed")
            print(f"nightly job on the sample line, {label}: {wall:.1f} s wall")
            if label == "cold":
                print("\n".join("  " + ln for ln in r.stdout.splitlines()[1:12]))


if __name__ == "__main__":
    main()
