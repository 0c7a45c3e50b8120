"""Absurd job values (issue 32) are one-line errors naming the job key, before any computation.

A sweep over every number key of every section (from the dataclasses, so a new key is swept
too): 1e308, -1e308, inf and nan are refused naming ``[section] key``; so are the specs that
used to hang or crash late (a ratio step of 1e-300 built 3e299 ratios; an adhesion range to
1e308 overflowed).
"""
from __future__ import annotations

import dataclasses
import textwrap

import pytest

from planner.errors import JobError
from planner.job.config import SECTIONS, load_job

NUMBER_KEYS = [(sec, f.name) for sec, cls in SECTIONS.items() for f in dataclasses.fields(cls)
               if f.name != "scenarios" and type(getattr(cls(), f.name)) in (int, float)]


def _job(tmp_path, section: str, body: str):
    (tmp_path / "lines" / "x").mkdir(parents=True, exist_ok=True)
    (tmp_path / "jobs").mkdir(exist_ok=True)
    p = tmp_path / "jobs" / "j.toml"
    head = '[job]\nlines = ["lines/x"]\n'
    if section == "job":
        p.write_text(head + body + "\n")
    else:
        p.write_text(head + f"[{section}]\n{body}\n")
    return p


def _refused(tmp_path, section, key, value_text) -> str:
    with pytest.raises(JobError) as e:
        load_job(_job(tmp_path, section, f"{key} = {value_text}"))
    msg = str(e.value)
    assert "\n" not in msg, msg  # one problem, one line
    assert f"[{section}] {key}:" in msg, msg
    return msg


def test_the_sweep_covers_the_number_keys():
    assert ("tables", "ds_m") in NUMBER_KEYS and ("parallel", "n_jobs") in NUMBER_KEYS
    assert ("job", "keep_runs") in NUMBER_KEYS and len(NUMBER_KEYS) >= 20


@pytest.mark.parametrize("section, key", [k for k in NUMBER_KEYS if k != ("job", "keep_runs")])
@pytest.mark.parametrize("value", ["1e308", "-1e308", "inf", "nan"])
def test_absurd_number_names_its_key(tmp_path, section, key, value):
    if section == "parallel" and key == "n_jobs":
        value = {"1e308": "1000000000000000", "-1e308": "-1000000000000000"}.get(value, value)
        if value in ("inf", "nan"):
            pytest.skip("an integer key: inf and nan are not integers (refused by type, tested elsewhere)")
    _refused(tmp_path, section, key, value)


@pytest.mark.parametrize("section, key, value, needle", [
    ("tables", "ds_m", "-1", "must be >= 0.01"),
    ("tables", "ds_m", "1e-300", "must be >= 0.01"),
    ("closed_loop", "step_s", "-1", "must be >= 0.01"),
    ("closed_loop", "step_s", "0.05", "designated times"),  # 60 s / 0.05 s = 1201 times per unit
    ("tables", "ratios", '"1.0:0.7:-0.1"', "step > 0"),
    ("tables", "ratios", '"1.0:0.7:1e-300"', "more than 1000 ratios"),
    ("tables", "ratios", '"1e308"', "ratio 1e+308 is outside (0, 1]"),
    ("tables", "ratios", '"nan"', "outside (0, 1]"),
    ("stops", "adhesion_kmh_s", '"0:1e308:1e-300"', "too many levels"),
    ("stops", "adhesion_kmh_s", '"2.5:3.5:-0.1"', "STEP > 0"),
    ("stops", "adhesion_kmh_s", '"1e308"', "outside [0.05, 18]"),
    ("stops", "approach_m", "1e-300", "must be >= 10"),
    ("margins", "supplement_percent", "-1", "must be >= 0"),
    ("conflicts", "release_s", "-1", "must be >= 0"),
    ("margins", "degraded_traction", "1e-300", "[0.1, 2]"),
    ("parallel", "n_jobs", "-5", "must be >= -1"),
])
def test_absurd_value_is_refused_with_why(tmp_path, section, key, value, needle):
    assert needle in _refused(tmp_path, section, key, value)


def test_ratios_never_name_the_cli_flag(tmp_path):
    assert "--ratios" not in _refused(tmp_path, "tables", "ratios", '"0.5:0.9:0.1"')


def test_scenario_values_are_bounded(tmp_path):
    body = textwrap.dedent("""
        scenarios = [{ name = "crush", load = 1e308, traction = 1.0 }]""")
    with pytest.raises(JobError) as e:
        load_job(_job(tmp_path, "closed_loop", body))
    msg = str(e.value)
    assert "[closed_loop] scenarios:" in msg and "'crush'" in msg and "\n" not in msg


@pytest.mark.parametrize("section, body", [
    ("tables", "ds_m = 0.01\nmin_target_kmh = 1.0\neval_offset_m = 0.0"),
    ("tables", "ds_m = 10.0\nmin_target_kmh = 600.0\nratios = \"1.0\""),
    ("stops", "approach_m = 10.0\nadhesion_kmh_s = \"0.05,18\""),
    ("closed_loop", "horizon_s = 999.0\nstep_s = 1.0"),  # 1000 designated times: the most accepted
    ("closed_loop", 'scenarios = [{ name = "crush", load = 3.0, traction = 0.1 }]'),
    ("margins", "supplement_percent = 100.0\ndegraded_adhesion_kmh_s = 0.05\ndegraded_traction = 0.1"),
    ("bundles", "valid_days = 1.0"),
    ("parallel", "n_jobs = 4096\ndask_lost_timeout_s = 1.0"),
])
def test_values_on_the_bounds_are_accepted(tmp_path, section, body):
    load_job(_job(tmp_path, section, body))
