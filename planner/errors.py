"""Domain errors, in one place.

Every error the user can cause derives from :class:`PlannerError` and carries a
stable ``key`` and a one-line message that says how to fix it. The CLI turns
them into a single line on stderr and a non-zero exit code, never a traceback.
"""
from __future__ import annotations

from dataclasses import dataclass


class PlannerError(Exception):
    """Base of every error the user can cause (bad input, infeasible request)."""

    key = "planner"
    exit_code = 1


@dataclass(frozen=True)
class Violation:
    """One broken rule in a line database.

    Parameters
    ----------
    file : str
        Table file name, e.g. ``"gradients.parquet"``.
    row : int or None
        0-based row number, or None for a whole-file problem.
    column : str or None
        Offending column, or None for a whole-row / whole-file problem.
    message : str
        What is wrong and, where it helps, how to fix it.
    row_id : str or None
        The row's id (``station_id``, ``start_m=4200.0``, ...) where it has one.
    rule : str
        The rule that found it, for a warning (the name of its function): warnings are grouped by it.
    """

    file: str
    row: int | None
    column: str | None
    message: str
    row_id: str | None = None
    rule: str = ""

    def __str__(self) -> str:
        where = self.file
        if self.row is not None:
            where += f" row {self.row}"
            if self.row_id:
                where += f" ({self.row_id})"
        if self.column:
            where += f" column {self.column}"
        return f"{where}: {self.message}"


class LineValidationError(PlannerError):
    """A line database broke one or more rules of docs/line-database.md."""

    key = "line.invalid"

    def __init__(self, line_dir: str, violations: list[Violation], total: int | None = None):
        self.line_dir = line_dir
        self.violations = list(violations)
        self.total = total if total is not None else len(self.violations)
        head = str(self.violations[0]) if self.violations else "invalid"
        super().__init__(f"{line_dir}: {self.total} problem(s); first: {head}")


class InputError(PlannerError):
    """Bad user input that is not a line-database rule (CLI option, job file, ...)."""

    key = "input"


class UnknownNameError(InputError):
    """A station, train type or train that the line database does not have."""

    key = "input.unknown"


class InfeasibleError(PlannerError):
    """The request cannot be met by any trajectory (limits too tight, too little time)."""

    key = "infeasible"


class StallError(InfeasibleError):
    """A run stalls: tractive effort cannot overcome resistance and gradient (a physical verdict).

    Attributes
    ----------
    position_m : (float, float)
        Chainage interval [m] where the run's speed reached zero (between two grid nodes).
    load, traction_factor : float
        Conditions of the (first) stalled run of the batch.
    """

    key = "infeasible.stall"

    def __init__(self, message: str, position_m: tuple[float, float], load: float, traction_factor: float):
        super().__init__(message)
        self.position_m = (float(position_m[0]), float(position_m[1]))
        self.load = float(load)
        self.traction_factor = float(traction_factor)

    def __reduce__(self):  # raised in a worker process, it pickles back with its attributes
        return type(self), (str(self), self.position_m, self.load, self.traction_factor)


class BundleError(PlannerError):
    """An on-board DB bundle failed to build, open or verify."""

    key = "bundle"


class JobError(PlannerError):
    """A job file is wrong, or a step of the nightly job failed."""

    key = "job"


class SourceError(InputError):
    """A source file for ``planner import`` is malformed; the message names file, element and field."""

    key = "input.source"


class SourceProblems(SourceError):
    """Every problem found in one source file, so that one run of ``planner import`` lists them all."""

    def __init__(self, source: str, problems: list[str]):
        self.problems = list(problems)
        super().__init__(f"{source}: {len(self.problems)} problems in the source (each listed above); fix them "
                         f"and import again")
