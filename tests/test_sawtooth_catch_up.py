"""A late sawtooth train told to go faster powers out of its coasting band (issue 37).

The integrator applies a controller's command at a decision node (``simulate(controller=...)``).
A sawtooth vehicle in its coasting band powers again only at the band's lower edge; where the
run cannot slow to it (here: level track and no resistance, so coasting holds the speed; on
the sample, E6 on -4 permille), a run told to go as fast as it can would coast on for ever. A
command that lifts a run's cruise cap (the time-keeping mode, late: flat out) ends its coasting: it
powers from there, as a driver or ATO told to catch up does. A cap raised to a finite speed, or a
raised ratio, keeps the band. Closed forms below; the default test train has a = 1 m/s² at full power
(300 kN on 300 t, no resistance) and brakes at 1 m/s².
"""
from __future__ import annotations

import numpy as np
import pytest

from planner.line import testing
from planner.physics.run_curve import Command, simulate
from planner.physics.track import make_track
from planner.tables.timekeeping import drive

L = 2000.0
V = 100 / 3.6          # line maximum [m/s]
C = 95 / 3.6           # first cruise cap [m/s]: inside the 10 km/h band below V
S_UP = 600.0           # where the cap is lifted [m]
TOL_S = 0.05           # docs/design.md §2: closed-form running times within 0.05 s at the 1 m step


def _line(cruise: str):
    return testing.line(length_m=L, train_types=[testing.train_type("T", cruise=cruise, coast_band_kmh=10.0)])


def _lift_cap(s_m, state):
    """Cap C from departure; at S_UP the cap is lifted (the train is late: as fast as it can)."""
    n = state.t_s.size
    if s_m == 0.0:
        return Command(np.ones(n), np.full(n, C))
    if s_m == S_UP:
        return Command(np.ones(n), np.full(n, np.inf))
    return None


def _run(cruise: str) -> float:
    line = _line(cruise)
    tr = make_track(line, "T", "S0", "S1", nodes_m=[S_UP])
    res = simulate(tr, line.train_type("T"), 1.0, controller=_lift_cap, decision_m=[0.0, S_UP])
    return float(res.time_s[0])


def powered_at_s_up() -> float:
    """a = 1 to C (C²/2 m), C to S_UP, a = 1 to V ((V² − C²)/2 m), V until the stopping curve
    (V²/2 m before the marker), brake at 1 to the marker."""
    x_v = L - V * V / 2 - S_UP - (V * V - C * C) / 2
    assert C * C / 2 < S_UP and x_v > 0
    return C + (S_UP - C * C / 2) / C + (V - C) + x_v / V + V


def coasting_on() -> float:
    """a = 1 to C, coasting at C (no resistance, level: the speed stays above the band's lower edge
    V − 10 km/h for ever) until the stopping curve (C²/2 m before the marker), brake at 1."""
    return C + (L - C * C) / C + C


def test_closed_forms_differ_by_more_than_the_tolerance():
    assert coasting_on() - powered_at_s_up() > 1.5  # the lateness the old rule left: about 1.9 s


@pytest.mark.parametrize("cruise", ["sawtooth", "constant"])
def test_a_raised_cap_is_met_at_full_power(cruise):
    """Sawtooth: coasting at C since it met the cap, it powers at S_UP. Constant cruise: it held C and
    powers at S_UP whatever the rule (unchanged by it). Both reach V and arrive at the closed form."""
    assert abs(_run(cruise) - powered_at_s_up()) < TOL_S


def test_a_late_sawtooth_train_powers_in_closed_loop():
    """The time-keeping controller. A relaxed schedule has the train cruise below C, coasting in its band
    (level, no resistance: at a constant speed above the band's lower edge). Near S_UP the arrival is
    brought forward to the closed form of powering to V from C at S_UP, which the train (below C) cannot
    quite make: late, it goes flat out (cap lifted). A run never above C arrives at ``coasting_on`` or
    later (1.9 s after the new schedule); this one must power, and arrive when its own flat-out
    look-ahead (which powers) said."""
    line = _line("sawtooth")
    tr = make_track(line, "T", "S0", "S1")
    train = line.train_type("T")
    t_change = C + (S_UP - C * C / 2) / C
    r = drive(tr, train, coasting_on() + 4.0, changes=[(t_change, powered_at_s_up())])
    at_change = np.searchsorted(r.t_s, t_change)
    assert r.v_ms[at_change] <= C and r.v_ms[at_change] > V - 10 / 3.6  # in its band, below C
    assert r.changes[-1].shortfall_s > 0.0  # late: flat out
    assert r.time_s < coasting_on() - 1.5
    assert abs(r.time_s - r.changes[-1].earliest_s) < TOL_S
    assert r.arrival_error_s < 0.5


def test_a_raised_ratio_keeps_the_band():
    """A raised ratio (the ratio modes, aiming by tables (b)-(d), which step their ratio changes with the
    band kept) does not end the coasting: ratio 0.95 (target C), then 1.0 at S_UP, coasts on at C."""
    line = _line("sawtooth")
    tr = make_track(line, "T", "S0", "S1", nodes_m=[S_UP])

    def raise_ratio(s_m, state):
        return np.full(state.t_s.size, 0.95 if s_m == 0.0 else 1.0)

    res = simulate(tr, line.train_type("T"), 1.0, controller=raise_ratio, decision_m=[0.0, S_UP])
    assert abs(float(res.time_s[0]) - coasting_on()) < TOL_S


def test_a_cap_raised_below_the_line_speed_keeps_the_band():
    """Cap C, then 97 km/h at S_UP (below V, and C is inside its band): the run coasts on at C."""
    line = _line("sawtooth")
    tr = make_track(line, "T", "S0", "S1", nodes_m=[S_UP])

    def nudge(s_m, state):
        return Command(np.ones(state.t_s.size), np.full(state.t_s.size, C if s_m == 0.0 else 97 / 3.6))

    res = simulate(tr, line.train_type("T"), 1.0, controller=nudge, decision_m=[0.0, S_UP])
    assert abs(float(res.time_s[0]) - coasting_on()) < TOL_S
