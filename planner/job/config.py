"""Job files (TOML): what the nightly job computes and where it publishes.

A job file is strict: an unknown key or a bad value is a :class:`JobError`
that names the file and the key (``jobs/nightly.toml: [tables] ratios: ...``);
every problem of the file is reported at once, one per line.
Every section is optional and has documented defaults, so the smallest job is

.. code-block:: toml

    [job]
    lines = ["lines/sample"]

Paths in a job file are relative to the job file's folder's parent project
root: the folder that contains ``jobs/`` (i.e. relative to the job file's
grand-parent when it lives in a ``jobs`` folder, else to the job file's own
folder), so ``make run`` works from a fresh clone.
"""
from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from planner.errors import JobError
from planner.tables.eval_points import MIN_INTERVAL_M


@dataclass(frozen=True)
class JobSection:
    name: str = "nightly"
    """Job name, shown in the summary and the run manifest."""
    lines: tuple[str, ...] = ("lines/sample",)
    """Line-database folders to plan."""
    train_types: tuple[str, ...] = ()
    """Train types to plan; empty = every train type of each line."""
    output_root: str = "outputs"
    """Where runs are published: OUTPUT_ROOT/<run_id>/ and OUTPUT_ROOT/latest."""
    keep_runs: int = 5
    """How many complete runs to keep (older ones are deleted after a publish)."""
    run_date: str = ""
    """The run's date (YYYY-MM-DD) stamped on every dataset row; "" = the UTC date when `planner run` starts."""


@dataclass(frozen=True)
class TablesSection:
    ratios: str = "1.0:0.7:0.1,0.7:floor:0.05"
    """Ratio grid SPEC: comma-separated START:STOP:STEP ranges or plain ratios; `floor` is the ratio where
    ratio × the leg's maximum = min_target_kmh."""
    min_target_kmh: float = 20.0
    """Each leg's grid stops where ratio × the train's highest on-board maximum on that leg reaches this speed."""
    eval_offset_m: float = 200.0
    """Evaluation point this far after departure."""
    eval_interval_m: float = 0.0
    """Odometer evaluation points at this regular interval after the point after departure [m]; 0 = none (beacons only)."""
    eval_auto_s: float = 30.0
    """On a leg with no beacon evaluation point (and eval_interval_m = 0): odometer points every this many seconds of
    running at the leg's maximum speed for the train (interval rounded to 10 m, at least 50 m); 0 = none."""
    ds_m: float = 1.0
    """Integration step in running distance [m]."""


@dataclass(frozen=True)
class StopsSection:
    adhesion_kmh_s: str = "2.5:3.5:0.1"
    """Adhesion sweep START:STOP:STEP in km/h/s: the rail's condition, absolute. Each train type gets the levels at
    or below min(brake_comfort_kmh_s, stop_brake_kmh_s), and that cap in place of every level above it."""
    approach_m: float | str = "auto"
    """Pattern start distance before the stop marker where no TASC beacon exists [m]; "auto": the line's
    approach_m, else where the train, at the minimum-time run's speed, must start braking at its lowest
    adhesion level, plus 10 %."""


@dataclass(frozen=True)
class Scenario:
    name: str
    load: float = 0.0
    traction: float = 1.0


@dataclass(frozen=True)
class ClosedLoopSection:
    modes: tuple[str, ...] = ("nearest", "adaptive")
    """On-board ratio-choice modes to prove."""
    horizon_s: float = 60.0
    """Designated times from the minimum to minimum + horizon_s."""
    step_s: float = 1.0
    scenarios: tuple[Scenario, ...] = (
        Scenario("nominal", 0.0, 1.0),
        Scenario("perturbed", 1.0, 0.9),
    )


@dataclass(frozen=True)
class MarginsSection:
    supplement_percent: float = 3.0
    """Rule: supplement = percent of the minimum running time ..."""
    supplement_min_per_100km: float = 1.0
    """... plus this many minutes per 100 km."""
    tight_threshold_s: float = 5.0
    """Remaining margin (scheduled − degraded minimum) below this is flagged `tight`."""
    bad_day_load: bool = True
    """The bad day (degraded scenario) includes a heavier train: on/off ..."""
    degraded_load: float = 1.0
    """... and its load factor (0 empty … 1 full)."""
    bad_day_traction: bool = True
    """The bad day includes weak traction (low catenary voltage): on/off ..."""
    degraded_traction: float = 0.9
    """... and its traction factor (tractive effort × this)."""
    bad_day_adhesion: bool = True
    """The bad day includes low adhesion in the stop (minimum-time stopping pattern): on/off ..."""
    degraded_adhesion_kmh_s: float = 0.0
    """... and its adhesion-limited deceleration [km/h/s]; 0 = the lowest level of the [stops] sweep."""
    arrival_error_threshold_s: float = 10.0
    """A leg whose closed loop misses the designated arrival by more than this is flagged `inaccurate` [s]; 0 = off."""


@dataclass(frozen=True)
class BundlesSection:
    signing_key: str = ""
    """Path of the Ed25519 private key (PEM). Empty: env PLANNER_SIGNING_KEY, else a development key if allowed."""
    allow_development_key: bool = False
    """With no key configured, sign with a generated development key under OUTPUT_ROOT/.dev-key (bundles marked
    `development`, refused by vehicles) instead of failing. For test runs only."""
    valid_days: float = 30.0
    """Bundles expire this many days after the run's build time; a run re-issues them when half of it has passed."""


@dataclass(frozen=True)
class ConflictsSection:
    enabled: bool = True
    """Check the timetable for route conflicts where the line has a track network."""
    setting_s: float = 10.0
    """Route setting time before the approach starts [s]."""
    approach_s: float = 20.0
    """Sight/reaction and approach time before the train reaches a resource [s]."""
    release_s: float = 5.0
    """Route release time after the tail clears [s]."""
    terminal_s: float = 0.0
    """How long a train keeps its destination platform after arriving [s]."""
    node_kinds: tuple[str, ...] = ("switch",)
    """Node kinds occupied as resources of their own (sections are always checked)."""


@dataclass(frozen=True)
class ParallelSection:
    backend: str = "local"
    """`local` (joblib loky processes) or `dask` (futures on a dask.distributed cluster, see planner.io.parallel)."""
    n_jobs: int = -1
    """Worker processes for the local backend; -1 = all cores."""
    scheduler: str = ""
    """Dask scheduler address (tcp://host:8786) for backend = "dask"."""
    dask_lost_timeout_s: float = 60.0
    """With backend = "dask": end the run with an error when the cluster has had no workers, or the scheduler has
    been unreachable, for this long [s]."""


@dataclass(frozen=True)
class DaySection:
    day: str = ""
    """The operating day planned (YYYY-MM-DD; `planner run --day` overrides it); "" = the next operating day in
    time_zone when the run starts (a production job). The sample job names a fixed day, so its runs repeat."""
    start_hour: int = 3
    """Local hour at which an operating day starts and the previous one ends (03:00 to 03:00 next day)."""
    time_zone: str = ""
    """IANA time zone of the job's lines (e.g. Asia/Tokyo): restrictions' validity and timetable times are local
    times there; "" = UTC, only for a job without feeds."""
    feeds: tuple[str, ...] = ()
    """Daily feed folder of each line of [job] lines, in the same order (restrictions, calendar); empty = no daily
    inputs: no temporary restrictions, every timetable train runs every day (docs/operating-day.md)."""


@dataclass(frozen=True)
class Job:
    path: str
    root: str
    job: JobSection = field(default_factory=JobSection)
    tables: TablesSection = field(default_factory=TablesSection)
    stops: StopsSection = field(default_factory=StopsSection)
    closed_loop: ClosedLoopSection = field(default_factory=ClosedLoopSection)
    margins: MarginsSection = field(default_factory=MarginsSection)
    bundles: BundlesSection = field(default_factory=BundlesSection)
    conflicts: ConflictsSection = field(default_factory=ConflictsSection)
    parallel: ParallelSection = field(default_factory=ParallelSection)
    day: DaySection = field(default_factory=DaySection)

    def resolve(self, p: str) -> Path:
        """A path from the job file, resolved against the project root."""
        q = Path(p)
        return q if q.is_absolute() else Path(self.root) / q

    def parameters(self) -> dict[str, Any]:
        """Every parameter as plain data (for digests and the run manifest)."""
        d = dataclasses.asdict(self)
        d.pop("path")
        d.pop("root")
        return d


SECTIONS = {
    "job": JobSection,
    "tables": TablesSection,
    "stops": StopsSection,
    "closed_loop": ClosedLoopSection,
    "margins": MarginsSection,
    "bundles": BundlesSection,
    "conflicts": ConflictsSection,
    "parallel": ParallelSection,
    "day": DaySection,
}


def _check_type(where: str, value: Any, default: Any) -> Any:
    """Coerce ``value`` to the type of ``default`` or raise with ``where``."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise JobError(f"{where}: expected true or false, found {value!r}")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise JobError(f"{where}: expected an integer, found {value!r}")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise JobError(f"{where}: expected a number, found {value!r}")
        return float(value)
    if default == "auto" and isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)  # a number-or-"auto" key (approach_m)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise JobError(f"{where}: expected a string, found {value!r}")
        return value
    if isinstance(default, tuple):
        if not isinstance(value, list):
            raise JobError(f"{where}: expected a list, found {value!r}")
        return tuple(value)
    return value


class _Problems(list):
    """Problems found in a job file; all of them are reported together."""

    def __init__(self):
        super().__init__()
        self.keys: set[str] = set()  # "section.key" already reported (value fell back to its default)

    def add(self, msg: str, key: str = "") -> None:
        if key:
            self.keys.add(key)
        self.append(msg)


def _section(file: str, name: str, cls, data: Any, problems: _Problems):
    if not isinstance(data, dict):
        problems.add(f"{file}: [{name}] must be a table, found {data!r}")
        return cls()
    known = {f.name: f for f in dataclasses.fields(cls)}
    defaults = cls()
    kwargs = {}
    for key, value in data.items():
        where = f"{file}: [{name}] {key}"
        try:
            if key not in known:
                raise JobError(f"{where}: unknown key; known keys: {', '.join(known)}")
            if cls is ClosedLoopSection and key == "scenarios":
                kwargs[key] = _scenarios(where, value)
                continue
            v = _check_type(where, value, getattr(defaults, key))
            if isinstance(v, tuple) and not all(isinstance(x, str) for x in v):
                raise JobError(f"{where}: expected a list of strings, found {value!r}")
            kwargs[key] = v
        except JobError as e:
            problems.add(str(e), f"{name}.{key}")
    return cls(**kwargs)


def _scenarios(where: str, value: Any) -> tuple[Scenario, ...]:
    if not isinstance(value, list) or not value:
        raise JobError(f"{where}: expected a non-empty list of {{name, load, traction}} tables")
    out = []
    for i, item in enumerate(value):
        w = f"{where}[{i}]"
        if not isinstance(item, dict):
            raise JobError(f"{w}: expected a table {{name, load, traction}}, found {item!r}")
        extra = set(item) - {"name", "load", "traction"}
        if extra:
            raise JobError(f"{w}: unknown key {sorted(extra)[0]!r}; known keys: name, load, traction")
        if "name" not in item or not isinstance(item["name"], str):
            raise JobError(f"{w}: needs a string `name`")
        from planner.io.paths import PATH_ID_RULE, is_path_id

        if not is_path_id(item["name"]):  # a partition value of the closed-loop datasets
            raise JobError(f"{w}: name {item['name']!r} cannot name a partition; {PATH_ID_RULE}")
        out.append(Scenario(
            item["name"],
            _check_type(f"{w} load", item.get("load", 0.0), 0.0),
            _check_type(f"{w} traction", item.get("traction", 1.0), 1.0),
        ))
    return tuple(out)


def _validate(file: str, job: Job, problems: _Problems) -> None:
    """Value rules that types alone do not catch; each names the key."""
    def bad(section: str, key: str, msg: str):
        if f"{section}.{key}" not in problems.keys:  # a value that failed its type check is not judged again
            problems.add(f"{file}: [{section}] {key}: {msg}")

    if not job.job.lines:
        bad("job", "lines", "name at least one line-database folder")
    if job.job.keep_runs < 1:
        bad("job", "keep_runs", f"must be at least 1, found {job.job.keep_runs}")
    if job.job.run_date:
        import datetime

        try:
            datetime.date.fromisoformat(job.job.run_date)
        except ValueError:
            bad("job", "run_date", f"expected a date YYYY-MM-DD (or \"\" for today), found {job.job.run_date!r}")
    out = job.resolve(job.job.output_root)
    base = out
    while not base.exists() and base != base.parent:
        base = base.parent
    if not base.is_dir():
        bad("job", "output_root", f"{out}: {base} is a file, not a folder; name a folder for the published runs")
    if not 0 < job.tables.ds_m <= 10:
        bad("tables", "ds_m", f"must be in (0, 10] m, found {job.tables.ds_m}")
    if job.tables.min_target_kmh <= 0:
        bad("tables", "min_target_kmh", "must be positive")
    if job.tables.eval_offset_m < 0:
        bad("tables", "eval_offset_m", "must be ≥ 0")
    if job.tables.eval_interval_m != 0 and not job.tables.eval_interval_m >= MIN_INTERVAL_M:
        bad("tables", "eval_interval_m", f"must be 0 (beacons only) or at least {MIN_INTERVAL_M:g} m, "
                                         f"found {job.tables.eval_interval_m}")
    if not (math.isfinite(job.tables.eval_auto_s) and job.tables.eval_auto_s >= 0):
        bad("tables", "eval_auto_s", f"must be 0 (no fill) or a number of seconds > 0, found {job.tables.eval_auto_s}")
    a = job.stops.approach_m
    if a != "auto" and (isinstance(a, (str, bool)) or not a > 0):
        bad("stops", "approach_m", 'must be a positive number of metres, or "auto" (from the physics)')
    if job.closed_loop.horizon_s < 0 or job.closed_loop.step_s <= 0:
        bad("closed_loop", "horizon_s/step_s", "horizon must be ≥ 0 and step > 0")
    for s in job.closed_loop.scenarios:
        if s.load < 0 or not 0 < s.traction <= 2:
            bad("closed_loop", "scenarios", f"scenario {s.name!r}: load ≥ 0 and 0 < traction ≤ 2")
    m = job.margins
    if m.tight_threshold_s < 0:
        bad("margins", "tight_threshold_s", "must be ≥ 0")
    if not 0 <= m.degraded_load <= 1:
        bad("margins", "degraded_load", f"must lie between 0 (empty) and 1 (full), found {m.degraded_load:g}")
    if not 0 < m.degraded_traction <= 2:
        bad("margins", "degraded_traction", f"must lie in (0, 2], found {m.degraded_traction:g}")
    if m.degraded_adhesion_kmh_s < 0:
        bad("margins", "degraded_adhesion_kmh_s", "must be > 0 km/h/s, or 0 for the lowest level of the sweep")
    if not (math.isfinite(m.arrival_error_threshold_s) and m.arrival_error_threshold_s >= 0):
        bad("margins", "arrival_error_threshold_s", f"must be a number of seconds ≥ 0 (0 = off), "
                                                    f"found {m.arrival_error_threshold_s}")
    if job.parallel.backend not in ("local", "dask"):
        bad("parallel", "backend", f"must be \"local\" or \"dask\", found {job.parallel.backend!r}")
    if job.parallel.backend == "dask" and not job.parallel.scheduler:
        bad("parallel", "scheduler", "backend = \"dask\" needs a scheduler address, e.g. tcp://127.0.0.1:8786")
    if not 0 < job.bundles.valid_days <= 3660:
        bad("bundles", "valid_days", f"must be in (0, 3660] days, found {job.bundles.valid_days}")
    if not 0 < job.parallel.dask_lost_timeout_s <= 86400:
        bad("parallel", "dask_lost_timeout_s", f"must be in (0, 86400] s, found {job.parallel.dask_lost_timeout_s}")
    if job.parallel.n_jobs == 0 or job.parallel.n_jobs < -1:
        bad("parallel", "n_jobs", f"must be -1 (all cores) or ≥ 1, found {job.parallel.n_jobs}")
    for p in job.job.lines:
        if not job.resolve(p).is_dir():
            bad("job", "lines", f"line folder {p!r} does not exist (resolved to {job.resolve(p)})")
    from planner.job.day import day_problems

    for key, msg in day_problems(job):
        bad("day", key, msg)


def project_root_for(job_path: Path) -> Path:
    """The folder job paths are relative to: the parent of ``jobs/``, else the job file's folder."""
    folder = job_path.resolve().parent
    return folder.parent if folder.name == "jobs" else folder


def load_job(path: str | Path) -> Job:
    """Read and check a job file; raise :class:`JobError` naming the key on any problem."""
    p = Path(path)
    file = str(path)
    if not p.is_file():
        raise JobError(f"{file}: job file not found")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise JobError(f"{file}: not valid TOML: {e}") from None
    except UnicodeDecodeError:
        raise JobError(f"{file}: not a UTF-8 text file") from None
    except OSError as e:  # no permission to read it, an I/O error
        raise JobError(f"{file}: cannot read the job file ({e.strerror or e}); check its permissions") from None
    kwargs: dict[str, Any] = {}
    problems = _Problems()
    for name, value in data.items():
        if name not in SECTIONS:
            problems.add(f"{file}: unknown section [{name}]; known sections: {', '.join(SECTIONS)}")
            continue
        kwargs[name] = _section(file, name, SECTIONS[name], value, problems)
    job = Job(path=file, root=str(project_root_for(p)), **kwargs)
    _validate(file, job, problems)
    if len(problems) == 1:
        raise JobError(problems[0])
    if problems:  # every problem at once, one per line, so one edit fixes them all
        raise JobError(f"{file}: {len(problems)} problems\n" + "\n".join(f"  {x}" for x in problems))
    return job
