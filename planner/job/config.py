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
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from planner.errors import InputError, JobError
from planner.line.schema import ACCEL, MAX_CHAINAGE_M, MAX_SPEED_KMH, Range
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
    """The run's date (YYYY-MM-DD), a partition folder of every dataset (run_date=); "" = the UTC date when
    `planner run` starts."""


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
class RobustnessSection:
    days: int = 0
    """Days simulated with random primary delays (Monte Carlo); 0 = none (the predicted day is always computed)."""
    seed: int = 1
    """Seed of the primary delays: the same seed gives the same bytes."""
    min_dwell_s: float = 20.0
    """Minimum dwell at a stop [s]: a late train departs no earlier than arrival + this."""
    min_dwell: tuple = ()
    """Exceptions: a list of {station_id, train_type ("*" any), min_dwell_s} tables; the last that matches wins."""
    delays: tuple = ()
    """Primary delays: a list of {kind, distribution, train_type, probability, mean_s, file} tables
    (docs/robustness.md)."""
    connections: str = ""
    """Optional Parquet file of turnarounds and connections (from_train, to_train, station_id, min_s)."""


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
    robustness: RobustnessSection = field(default_factory=RobustnessSection)
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
    "robustness": RobustnessSection,
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
        if not math.isfinite(value):  # TOML has inf and nan
            raise JobError(f"{where}: expected a finite number, found {value!r}")
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
            if cls is RobustnessSection and key in ("delays", "min_dwell"):
                from planner.job.robustness import parse_tables

                kwargs[key] = parse_tables(where, key, value)
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


_LINE = 2 * MAX_CHAINAGE_M
_SECONDS = "route setting, approach and release take seconds to minutes, not hours"
RANGES: dict[tuple[str, str], Range] = {
    ("tables", "min_target_kmh"): Range(1.0, MAX_SPEED_KMH, "from walking pace (1 km/h) to 600 km/h, every line's "
                                                            "maximum at most (the line database's bound)"),
    ("tables", "eval_offset_m"): Range(0.0, _LINE, "no interstation is longer than a line can be (20,000 km)"),
    ("tables", "eval_interval_m"): Range(0.0, _LINE, "no interstation is longer than a line can be (20,000 km)"),
    ("tables", "ds_m"): Range(0.01, 10.0, "a step under 1 cm resolves nothing a train does and multiplies the work; "
                                          "over 10 m misses short restrictions"),
    ("stops", "approach_m"): Range(10.0, _LINE, "a stop approach is at least one step of the coarsest ds_m "
                                                "(10 m; shorter has no grid to sweep) and no longer than a line "
                                                "can be (20,000 km)"),
    ("tables", "eval_auto_s"): Range(0.0, 3_600.0, "0 (no odometer points on a leg without beacons) or seconds "
                                                   "of running between points; over an hour is no point at all"),
    ("closed_loop", "horizon_s"): Range(0.0, 86_400.0, "designated times more than a day after the minimum "
                                                      "running time are no timetable"),
    ("closed_loop", "step_s"): Range(0.01, 86_400.0, "designated times closer than 10 ms apart differ by nothing "
                                                    "a driver or the on-board unit can do"),
    ("margins", "supplement_percent"): Range(0.0, 100.0, "a supplement is a share of the minimum running time: "
                                                         "0-100 %"),
    ("margins", "supplement_min_per_100km"): Range(0.0, 100.0, "a supplement of minutes per 100 km; over 100 "
                                                                "min/100 km is a stop, not a supplement"),
    ("margins", "tight_threshold_s"): Range(0.0, 3_600.0, "a margin threshold over an hour flags every leg"),
    ("margins", "arrival_error_threshold_s"): Range(0.0, 3_600.0, "0 (off) or an arrival error in seconds; over "
                                                                  "an hour flags nothing a timetable can use"),
    ("margins", "degraded_adhesion_kmh_s"): Range(0.0, ACCEL.hi, "0 (the lowest level of the sweep) or an "
                                                                 "adhesion of at most 18 km/h/s (5 m/s²)"),
    ("bundles", "valid_days"): Range(1.0, 3_660.0, "bundles are loaded overnight: a shorter validity expires "
                                                   "before they reach the vehicles; over 10 years is no expiry"),
    ("conflicts", "setting_s"): Range(0.0, 3_600.0, _SECONDS),
    ("conflicts", "approach_s"): Range(0.0, 3_600.0, _SECONDS),
    ("conflicts", "release_s"): Range(0.0, 3_600.0, _SECONDS),
    ("conflicts", "terminal_s"): Range(0.0, 86_400.0, "a train keeps its destination platform at most a day"),
    ("robustness", "days"): Range(0.0, 1_000_000.0, "0 (none) to a million simulated days"),
    ("robustness", "seed"): Range(0.0, 2.0 ** 63 - 1, "a seed is a non-negative integer"),
    ("robustness", "min_dwell_s"): Range(0.0, 3_600.0, "a minimum dwell of seconds to minutes"),
    ("parallel", "n_jobs"): Range(-1.0, 4_096.0, "-1 (all cores) or a number of worker processes"),
    ("parallel", "dask_lost_timeout_s"): Range(1.0, 86_400.0, "between a second and a day without workers"),
}
"""Bounds of the job's number keys, each with its reason: an absurd value (a negative step, 1e308) is
refused here, naming the key, instead of failing late in a computation."""
MAX_CLOSED_LOOP_TIMES = 1_000
"""Most designated times per closed-loop unit (horizon_s / step_s + 1): each is a closed-loop run per scenario
and mode."""
MAX_LOAD = 3.0
"""Heaviest scenario load factor: 300 % of the passenger mass at 100 % load (Tokyo's rush hour peaks near 200 %)."""


def _out_of_range(rng: Range, x: float) -> str:
    need = f"must be {'>' if rng.lo_open else '>='} {rng.lo:g}" if rng.below(x) else f"must be <= {rng.hi:g}"
    return f"{need}, found {x:g} (accepted {rng}: {rng.why})"


def _spec_error(e: InputError, flag: str, key: str) -> str:
    """A ratio or adhesion spec error worded for the job file: its key, not the CLI flag."""
    return re.sub(rf"^{flag}:? ?", "", str(e)).replace(flag, key)


def _validate_specs(job: Job, bad) -> None:
    """Parse the ratio grid and the adhesion sweep now, so a bad spec names its key before any work."""
    from planner.line.units import KMH
    from planner.stopping.sweep import adhesion_levels
    from planner.tables.ratios import ratio_grid

    target = RANGES[("tables", "min_target_kmh")]
    if not (target.below(job.tables.min_target_kmh) or target.above(job.tables.min_target_kmh)):
        try:  # the fastest line the schema allows has the lowest floor: below it no line keeps a ratio
            ratio_grid(job.tables.ratios, line_max_speed_ms=MAX_SPEED_KMH * KMH,
                       min_target_speed_ms=job.tables.min_target_kmh * KMH)
        except InputError as e:
            bad("tables", "ratios", _spec_error(e, "--ratios", "ratios"))
    try:
        levels = adhesion_levels(job.stops.adhesion_kmh_s)
    except InputError as e:
        bad("stops", "adhesion_kmh_s", _spec_error(e, "--adhesion", "adhesion_kmh_s"))
        return
    except OverflowError:  # START:STOP:STEP with an infinite count of levels
        bad("stops", "adhesion_kmh_s", f"{job.stops.adhesion_kmh_s!r} gives too many levels; use a larger STEP")
        return
    off = [x for x in levels if ACCEL.below(x) or ACCEL.above(x)]
    if off:
        bad("stops", "adhesion_kmh_s", f"level {off[0]:g} km/h/s is outside {ACCEL} ({ACCEL.why})")


def _validate(file: str, job: Job, problems: _Problems) -> None:
    """Value rules that types alone do not catch; each names the key."""
    def bad(section: str, key: str, msg: str):
        if f"{section}.{key}" not in problems.keys:  # a value already refused is not judged again
            problems.add(f"{file}: [{section}] {key}: {msg}", f"{section}.{key}")

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
    for (section, key), rng in RANGES.items():
        x = getattr(getattr(job, section), key)
        if isinstance(x, (str, bool)):  # "auto" for a number-or-"auto" key (approach_m): checked below
            continue
        if rng.below(x) or rng.above(x):
            bad(section, key, _out_of_range(rng, x))
    _validate_specs(job, bad)
    if job.tables.eval_interval_m != 0 and not job.tables.eval_interval_m >= MIN_INTERVAL_M:
        bad("tables", "eval_interval_m", f"must be 0 (beacons only) or at least {MIN_INTERVAL_M:g} m, "
                                         f"found {job.tables.eval_interval_m}")
    a = job.stops.approach_m
    if isinstance(a, (str, bool)) and a != "auto":
        bad("stops", "approach_m", 'must be a number of metres, or "auto" (from the physics)')
    cl = job.closed_loop
    n_times = cl.horizon_s / cl.step_s + 1 if cl.step_s > 0 else math.inf
    if n_times > MAX_CLOSED_LOOP_TIMES and "closed_loop.horizon_s" not in problems.keys:
        bad("closed_loop", "step_s", f"horizon_s / step_s gives {n_times:.3g} designated times per unit, more than "
                                     f"{MAX_CLOSED_LOOP_TIMES}; use a larger step_s or a shorter horizon_s")
    for s in cl.scenarios:
        if not 0 <= s.load <= MAX_LOAD or not 0.1 <= s.traction <= 2:
            bad("closed_loop", "scenarios", f"scenario {s.name!r}: load must lie in [0, {MAX_LOAD:g}] (full load "
                                            f"is 1) and traction in [0.1, 2] (nominal is 1); found load {s.load:g}, "
                                            f"traction {s.traction:g}")
    m = job.margins
    if not 0 <= m.degraded_load <= 1:
        bad("margins", "degraded_load", f"must lie between 0 (empty) and 1 (full), found {m.degraded_load:g}")
    if not 0.1 <= m.degraded_traction <= 2:
        bad("margins", "degraded_traction", f"must lie in [0.1, 2] (a tenth of the tractive effort at least; "
                                            f"nominal is 1), found {m.degraded_traction:g}")
    if 0 < m.degraded_adhesion_kmh_s < ACCEL.lo:
        bad("margins", "degraded_adhesion_kmh_s", f"must be 0 (the lowest level of the sweep) or in {ACCEL}, "
                                                  f"found {m.degraded_adhesion_kmh_s:g}")
    if job.parallel.backend not in ("local", "dask"):
        bad("parallel", "backend", f"must be \"local\" or \"dask\", found {job.parallel.backend!r}")
    if job.parallel.backend == "dask" and not job.parallel.scheduler:
        bad("parallel", "scheduler", "backend = \"dask\" needs a scheduler address, e.g. tcp://127.0.0.1:8786")
    if job.parallel.n_jobs == 0:
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
