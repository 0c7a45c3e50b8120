"""The hostile probes of issue 19 as tests, on a minimal job (tiny line, one train type, short sweeps).

One clean cold run fills a cache (4 tables + 4 stops + 4 closed-loop + 1 conflicts + 1 margins
entries). Each probe copies that cache and the development signing key into a fresh output root,
damages the copy, runs the job through the real entry point (``planner run``) and compares every
published file with the clean run's: it must exit 0 with byte-identical files (the damaged entries
recomputed, counted in one warning) or exit non-zero with one line and ``latest`` untouched.

Then the output root itself fails: a full disk (a small tmpfs; where mounting is not possible, ENOSPC
is simulated in the atomic writer) and a read-only file system.
"""
from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import pickle
import random
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from linedb import write_line_db
from planner.io.parquet import without_run
from planner.job.cache import SUFFIX, Cache
from planner.job.publish import latest_run
from test_network_cli import EDGES, NODES

VOLATILE = ("run_id", "timings_s", "units_computed", "units_reused", "changes")  # wall-clock, how a run got there, what it is compared with
KINDS = {"tables": 4, "stops": 4, "closed_loop": 4, "conflicts": 1, "margins": 1, "margin_leg": 4, "graph": 2,
         "charts": 2, "timetable": 1, "robustness": 1}  # speed-distance charts: the EMU10 train 101's legs A-B and
# B-C; margin legs: one per group; the running-time tables and the robustness page: one unit, the line is one section
# what the job keeps, beside the result
BESIDE = {"tables_kept": 4, "stops_kept": 4, "closed_loop_kept": 4, "conflicts_kept": 1}
# what the margins read of each part of the closed loop's datasets (a direction each), made with its files
FACTS = {"closed_loop_facts": 2}
# what the job keeps of its own work, not a unit: the line's sections (planner.job.steps.line_sections_kept)
KEPT = {"sections": 1}


def _job(project: Path, output_root: str) -> Path:
    p = project / "jobs" / f"{output_root.replace('/', '_')}.toml"
    p.parent.mkdir(exist_ok=True)
    p.write_text(textwrap.dedent(f"""
        [job]
        lines = ["lines/tiny"]
        output_root = "{output_root}"
        train_types = ["EMU10"]
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
        [parallel]
        n_jobs = 1
        [bundles]
        allow_development_key = true
    """))
    return p


def _cli(capsys, *args) -> tuple[int, str]:
    """``planner ARGS`` through the console entry point: (exit code, stderr)."""
    from planner.cli import main

    old = sys.argv
    sys.argv = ["planner", *map(str, args)]
    code = 0
    try:
        main()
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else 1
    finally:
        sys.argv = old
    return code, capsys.readouterr().err


def _published(root: Path) -> dict[str, str]:
    """SHA-256 of every file of the run ``latest`` points at; the manifest without its volatile keys."""
    run = root / "latest"
    out = {}
    for p in sorted(run.rglob("*")):
        if p.is_file():
            rel = without_run(p.relative_to(run).as_posix())  # a dataset's folders name its run
            if rel == "index.html" or rel.startswith("changes/"):
                continue  # the overview shows each step's timings; changes compare with an earlier run
            if rel.endswith(".html"):
                import re  # the report's "what changed since the last run" section, likewise

                text = p.read_text().replace(run.resolve().name, "RUN")  # every page names its run at the top
                if rel.startswith("report/"):
                    text = re.sub(r"<style>[^<]*</style><section class='changes'.*?</section>", "", text, flags=re.S)
                out[rel] = hashlib.sha256(text.encode()).hexdigest()
                continue
            if rel == "manifest.json":
                m = json.loads(p.read_text())
                m["parameters"]["job"].pop("output_root")  # each probe has its own
                m.get("rows", {}).pop("changes", None)  # rows of the comparison with an earlier run
                out[rel] = json.dumps({k: v for k, v in m.items() if k not in VOLATILE}, sort_keys=True)
            elif rel.endswith(".html") and rel.split("/")[0] in ("graph", "timetable"):
                # these pages name their run under the title (issue 36): compare the rest
                text = p.read_text().replace(run.resolve().name, "<run id>")
                out[rel] = hashlib.sha256(text.encode()).hexdigest()
            else:
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


@pytest.fixture(scope="module", autouse=True)
def _fixed_build_time():
    # bundles carry their build time: runs with the same SOURCE_DATE_EPOCH give the same bytes
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SOURCE_DATE_EPOCH", "1767225600")  # 2026-01-01T00:00:00Z
        yield


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    project = tmp_path_factory.mktemp("probes")
    write_line_db(project / "lines" / "tiny", nodes=NODES, edges=EDGES)
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    s = run_job(load_job(_job(project, "clean")), show_progress=False)
    assert s.computed == KINDS
    root = project / "clean"
    return project, root, _published(root)


def _entries(root: Path) -> dict[str, list[Path]]:
    return {k: sorted((root / ".cache" / k).rglob(f"*{SUFFIX}")) for k in (*KINDS, *KEPT)}


def _fresh_root(clean, name: str) -> tuple[Path, Path]:
    """An output root holding a copy of the clean run's cache and signing key, and its job file."""
    project, root, _ = clean
    new = project / name
    shutil.copytree(root / ".cache", new / ".cache")
    shutil.copytree(root / ".dev-key", new / ".dev-key")
    return new, _job(project, name)


def _flip_bits(p: Path, rnd: random.Random) -> None:
    data = bytearray(p.read_bytes())
    i = rnd.randrange(len(data))
    data[i] ^= 1 << rnd.randrange(8)
    p.write_bytes(bytes(data))


def _swap(a: Path, b: Path) -> None:
    da, db = a.read_bytes(), b.read_bytes()
    a.write_bytes(db)
    b.write_bytes(da)


def _damage(probe: str, e: dict[str, list[Path]], marker: Path) -> int:
    """Damage the cache copy; returns how many entries must be rejected."""
    rnd = random.Random(19)
    if probe == "bit_flips":  # one bit at a random place (header or payload) of every entry
        victims = [p for ps in e.values() for p in ps]
        for p in victims:
            _flip_bits(p, rnd)
        return len(victims)
    if probe == "swapped":  # three pairs within a kind, three pairs across kinds
        _swap(e["tables"][0], e["tables"][1])
        _swap(e["stops"][0], e["stops"][3])
        _swap(e["closed_loop"][1], e["closed_loop"][2])
        _swap(e["tables"][2], e["stops"][1])
        _swap(e["closed_loop"][0], e["margins"][0])
        _swap(e["conflicts"][0], e["tables"][3])
        return 12
    if probe == "truncated_or_empty":
        for p in (e["tables"][2], e["margins"][0], e["conflicts"][0]):
            p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
        for p in (e["stops"][1], e["closed_loop"][3], e["tables"][0], e["sections"][0]):
            p.write_bytes(b"")
        return 7
    if probe == "planted_pickle":  # in an entry's place, and as a stray file in the old layout
        evil = pickle.dumps(_Evil(marker))
        for p in (e["tables"][0], e["margins"][0]):
            p.write_bytes(evil)
        (e["stops"][0].parent / "planted.pkl").write_bytes(evil)
        return 2
    raise AssertionError(probe)


class _Evil:
    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (Path.write_text, (Path(self.marker), "code ran"))


PROBES = ["bit_flips", "swapped", "truncated_or_empty", "planted_pickle"]


@pytest.mark.parametrize("probe", PROBES)
def test_a_damaged_cache_never_reaches_a_published_file(clean, capsys, probe, tmp_path):
    root, job = _fresh_root(clean, f"probe_{probe}")
    marker = tmp_path / "marker"
    n_bad = _damage(probe, _entries(root), marker)
    code, err = _cli(capsys, "run", job, "--no-progress")
    assert code == 0, err
    assert _published(root) == clean[2]  # every published file byte-identical to the clean run's
    warnings = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and warnings[0].startswith(f"warning: {n_bad} cache entr"), err
    assert not marker.exists()
    rep = Cache(root / ".cache").verify()  # the rejected entries were replaced by good ones
    assert rep.good == sum(KINDS.values()) + sum(BESIDE.values()) + sum(FACTS.values()) + sum(KEPT.values()) \
        and not rep.bad
    manifest = json.loads((root / "latest" / "manifest.json").read_text())
    kept = {"bit_flips": 1, "truncated_or_empty": 1}.get(probe, 0)  # the sections made again: not a unit
    assert sum(manifest["units_computed"].values()) == n_bad - kept


def test_what_is_kept_beside_a_result_is_made_again_from_it_when_damaged(clean, capsys):
    """An entry beside a result (what the job keeps of it) that is damaged or missing is made again from the result,
    which is checked and decoded; no unit is computed again, the published files are the clean run's."""
    root, job = _fresh_root(clean, "beside")
    beside = {k: sorted((root / ".cache" / k).rglob(f"*{SUFFIX}")) for k in BESIDE}
    assert {k: len(v) for k, v in beside.items()} == BESIDE
    rnd = random.Random(5)
    for p in beside["tables_kept"] + beside["stops_kept"]:
        _flip_bits(p, rnd)
    for p in beside["closed_loop_kept"] + beside["conflicts_kept"]:  # made again from the result
        p.unlink()
    code, err = _cli(capsys, "run", job, "--no-progress")
    assert code == 0, err
    assert _published(root) == clean[2]
    manifest = json.loads((root / "latest" / "manifest.json").read_text())
    assert sum(manifest["units_computed"].values()) == 0
    rep = Cache(root / ".cache").verify()
    assert rep.good == sum(KINDS.values()) + sum(BESIDE.values()) + sum(FACTS.values()) + sum(KEPT.values()) \
        and not rep.bad


# --- the output root fails ---------------------------------------------------------------------
@contextlib.contextmanager
def _tmpfs(path: Path, size: str):
    """Mount a tmpfs of ``size`` at ``path``; yields False where mounting is not possible."""
    path.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0 or not shutil.which("mount"):
        yield False
        return
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], capture_output=True)
    if r.returncode != 0:
        yield False
        return
    try:
        yield True
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


def _copy_clean(clean, root: Path) -> str:
    """Put the clean run (published folder, ``latest``, cache, signing key) under ``root``; its run id."""
    src = clean[1]
    first = latest_run(src)
    for name in (".cache", ".dev-key", first):
        shutil.copytree(src / name, root / name, symlinks=True)
    os.symlink(first, root / "latest")
    return first


def _staging(root: Path) -> list[str]:
    return [p.name for p in root.iterdir() if p.name.startswith(".staging-")]


def _one_line_error(code: int, err: str, *needles: str) -> str:
    lines = err.strip().splitlines()
    assert code != 0 and len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def test_a_full_disk_ends_in_one_line_and_latest_stays(clean, capsys, monkeypatch):
    project = clean[0]
    root = project / "full"
    with _tmpfs(root, "4m") as mounted:
        first = _copy_clean(clean, root)
        job = _job(project, "full")
        before = _published(root)
        filler = root / "filler"
        if mounted:  # leave 64 KiB: the cache reads fine, the staged datasets do not fit
            st = os.statvfs(root)
            filler.write_bytes(b"\0" * (st.f_bavail * st.f_frsize - 64 * 1024))
        else:  # simulated: every atomic write fails as on a full disk
            import planner.io.atomic as atomic

            def full(path):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), path)

            monkeypatch.setattr(atomic, "_fsync_file", full)
        # --no-cache: the run must write (cache entries, then the staged run) and cannot
        code, err = _cli(capsys, "run", job, "--no-progress", "--no-cache")
        line = _one_line_error(code, err, "no space left on device", str(root),
                               "free space there", f"latest still points at {first}")
        with capsys.disabled():
            print(f"\nfull disk ({'tmpfs 4m' if mounted else 'simulated ENOSPC'}): {line}")
        assert latest_run(root) == first and _published(root) == before
        assert _staging(root) == []  # given back at once
        monkeypatch.undo()
        filler.unlink(missing_ok=True)
        (root / ".staging-r0009-0123456789").mkdir()  # as a killed run leaves it
        os.unlink(root / "latest")  # so that the next run publishes a new run (from the cache)
        code, err = _cli(capsys, "run", job, "--no-progress")
        assert code == 0, err
        assert latest_run(root) != first and _staging(root) == [] and _published(root) == clean[2]


def test_a_read_only_output_root_ends_in_one_line_and_latest_stays(clean, capsys):
    project = clean[0]
    root = project / "readonly"
    with _tmpfs(root, "4m") as mounted:
        if not mounted:
            pytest.skip("cannot mount a tmpfs here (needs root); the full-disk test covers the error path")
        first = _copy_clean(clean, root)
        job = _job(project, "readonly")
        before = _published(root)
        # a failed run's staging folder is on the disk when it goes read-only
        (root / ".staging-r0009-0123456789").mkdir()
        subprocess.run(["mount", "-o", "remount,ro", str(root)], check=True)
        try:
            code, err = _cli(capsys, "run", job, "--no-progress", "--no-cache")
            line = _one_line_error(code, err, "read-only file system", str(root), "mount it read-write",
                                   f"latest still points at {first}")
            with capsys.disabled():
                print(f"\nread-only root: {line}")
            assert latest_run(root) == first and _published(root) == before
        finally:
            subprocess.run(["mount", "-o", "remount,rw", str(root)], check=True)
        # --no-cache: recompute every unit and publish a new run although nothing changed
        code, err = _cli(capsys, "run", job, "--no-progress", "--no-cache")
        assert code == 0, err
        assert latest_run(root) != first and _staging(root) == [] and _published(root) == clean[2]
        manifest = json.loads((root / "latest" / "manifest.json").read_text())
        assert manifest["units_computed"] == KINDS
