"""Killing a build partway never leaves a partial bundle under the final name.

A child process builds a bundle and is SIGKILLed at seeded random moments: some
at random delays over the whole build, some right after its temporary file
appears (mid-write). Afterwards the final name must hold nothing, or a complete
bundle that verifies: the previous one, or the new one if the build finished
before the kill. The child slows its own writes (small chunks, a short sleep
each) so that the write window is wide enough to be hit; the build code it runs
is unchanged.
"""
from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

from planner.bundle.verify import read_bundle, verify_bundle
from planner.bundle import signing

HERE = Path(__file__).parent
NAME = "tl_down_E10.pdb"
CHILD = r"""
import os, sys, time
sys.path.insert(0, sys.argv[3])
from test_bundle_support import make_line, all_tables, release
from planner.io import atomic
from planner.bundle.container import build_bundle
tables = all_tables(make_line(), pad_rows=40000 + int(sys.argv[4]))  # variant -> different bytes
real_write = os.write
def slow_write(fd, data):
    time.sleep(0.002)
    return real_write(fd, data)
atomic._CHUNK = 4096
os.write = slow_write
print("ready", flush=True)
build_bundle(tables, line_id="tl", direction="down", train_type="E10", out_dir=sys.argv[1],
             private_key=sys.argv[2], line_digest="ab" * 32, release=release())
print("done", flush=True)
"""


def start(out: Path, key: Path, variant: int) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-c", CHILD, str(out), str(key), str(HERE), str(variant)],
                         stdout=subprocess.PIPE)
    assert p.stdout.readline() == b"ready\n"
    return p


def temp_files(out: Path) -> list[str]:
    return [n for n in os.listdir(out) if n != NAME]


def kill_at(p: subprocess.Popen, out: Path, rng: random.Random, on_temp: bool) -> None:
    if on_temp:
        seen = set(temp_files(out))
        deadline = time.monotonic() + 30.0
        while not set(temp_files(out)) - seen and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.001)
        time.sleep(rng.uniform(0.0, 0.03))
    else:
        time.sleep(rng.uniform(0.0, 0.5))
    p.send_signal(signal.SIGKILL)
    p.wait()
    p.stdout.close()


def final_state(out: Path, pub) -> bytes | None:
    path = out / NAME
    if not path.exists():
        return None
    verify_bundle(path, pub)  # raises if partial or altered
    return path.read_bytes()


def test_sigkill_never_leaves_a_partial_bundle(tmp_path):
    rng = random.Random(20240607)
    priv, pub = signing.generate_keypair(tmp_path / "keys")
    out = tmp_path / "out"
    out.mkdir()
    mid_write = 0

    # No previous bundle: afterwards nothing, or a complete one.
    for k in range(4):
        before = set(temp_files(out))
        kill_at(start(out, priv, 0), out, rng, on_temp=k % 2 == 1)
        mid_write += bool(set(temp_files(out)) - before)
        state = final_state(out, pub)
        if state is not None:  # it finished before the kill; start again from nothing
            (out / NAME).unlink()

    # A complete previous bundle.
    p = start(out, priv, 0)
    assert p.stdout.readline() == b"done\n"
    p.wait()
    p.stdout.close()
    previous = final_state(out, pub)
    assert previous is not None

    # Rebuilds with other content, killed: the previous bundle or the complete new one.
    for k in range(6):
        variant = k + 1
        before = set(temp_files(out))
        kill_at(start(out, priv, variant), out, rng, on_temp=k % 2 == 0)
        left = set(temp_files(out)) - before
        mid_write += bool(left)
        state = final_state(out, pub)
        assert state is not None, "the previous complete bundle disappeared"
        if state != previous:
            assert read_bundle(state, pub).tables["stop_samples"].num_rows == 40000 + variant + 16
            previous = state
        for n in left:  # leftovers of a kill are hidden temp files, never the bundle's name
            assert n.startswith(f".{NAME}.") and n.endswith(".tmp")
    assert mid_write >= 2, "no kill hit the write window; the test proved nothing"
