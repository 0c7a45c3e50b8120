"""Job files: defaults, strictness (unknown keys and bad values name the key), path resolution."""
from pathlib import Path

import pytest

from planner.errors import JobError
from planner.job.config import load_job


def _write(tmp_path, text):
    (tmp_path / "lines" / "x").mkdir(parents=True)
    (tmp_path / "jobs").mkdir()
    p = tmp_path / "jobs" / "j.toml"
    p.write_text(text)
    return p


def test_minimal_job_gets_defaults_and_resolves_against_project_root(tmp_path):
    job = load_job(_write(tmp_path, '[job]\nlines = ["lines/x"]\n'))
    assert job.job.lines == ("lines/x",)
    assert job.resolve("lines/x") == tmp_path.resolve() / "lines" / "x"
    assert job.tables.eval_offset_m == 200.0
    assert [s.name for s in job.closed_loop.scenarios] == ["nominal", "perturbed"]
    assert job.closed_loop.scenarios[1].load == 1.0 and job.closed_loop.scenarios[1].traction == 0.9
    assert job.parallel.backend == "local"


@pytest.mark.parametrize(
    "text, needle",
    [
        ('[job]\nlines = ["lines/x"]\nkeep = 3\n', "[job] keep: unknown key"),
        ('[job]\nlines = ["lines/x"]\n[tabels]\n', "unknown section [tabels]"),
        ('[job]\nlines = ["lines/x"]\nkeep_runs = "five"\n', "[job] keep_runs: expected an integer"),
        ('[job]\nlines = ["lines/x"]\nkeep_runs = 0\n', "[job] keep_runs: must be at least 1"),
        ('[job]\nlines = ["lines/nope"]\n', "[job] lines: line folder 'lines/nope' does not exist"),
        ('[job]\nlines = ["lines/x"]\n[tables]\nds_m = -1\n', "[tables] ds_m"),
        ('[job]\nlines = ["lines/x"]\n[parallel]\nbackend = "mpi"\n', "[parallel] backend"),
        ('[job]\nlines = ["lines/x"]\n[parallel]\nbackend = "dask"\n', "[parallel] scheduler"),
        ('[job]\nlines = ["lines/x"]\n[closed_loop]\nscenarios = [{name = "a", lod = 1}]\n',
         "[closed_loop] scenarios[0]: unknown key 'lod'"),
        ('[job]\nlines = "lines/x"\n', "[job] lines: expected a list"),
        ('[job\n', "not valid TOML"),
        ('[job]\nlines = ["lines/x"]\nrun_date = "23.11.2026"\n', "[job] run_date: expected a date YYYY-MM-DD"),
        ('[job]\nlines = ["lines/x"]\n[margins]\ndegraded_load = 2.0\n', "[margins] degraded_load: must lie between"),
    ],
)
def test_bad_job_names_the_key(tmp_path, text, needle):
    with pytest.raises(JobError) as e:
        load_job(_write(tmp_path, text))
    msg = str(e.value)
    assert needle in msg and "j.toml" in msg and "\n" not in msg


def test_an_unreadable_job_file_is_one_line(tmp_path, monkeypatch):
    job = _write(tmp_path, '[job]\nlines = ["lines/x"]\n')

    def denied(self, *a, **k):  # as for a user without read permission (root reads any file)
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_text", denied)
    with pytest.raises(JobError, match=r"j.toml: cannot read the job file \(Permission denied\); check its "):
        load_job(job)


def test_missing_job_file(tmp_path):
    with pytest.raises(JobError, match="job file not found"):
        load_job(tmp_path / "none.toml")


def test_run_date_is_part_of_the_inputs_digest(tmp_path):
    """Same inputs, another date: another run id (the date is a partition folder of every dataset)."""
    import dataclasses

    from planner.job.pipeline import _inputs_digest, resolve_run_date

    job = load_job(_write(tmp_path, '[job]\nlines = ["lines/x"]\nrun_date = "2026-11-23"\n'))
    assert resolve_run_date(job) == "2026-11-23"
    a = _inputs_digest(job, [], "k", resolve_run_date(job))
    assert a == _inputs_digest(job, [], "k", "2026-11-23")
    assert a != _inputs_digest(job, [], "k", "2026-11-24")
    today = dataclasses.replace(job, job=dataclasses.replace(job.job, run_date=""))
    assert len(resolve_run_date(today)) == 10
