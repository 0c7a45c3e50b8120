"""Forces of the running-theory model (planner.physics.dynamics): hand-computed values."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from planner.physics import dynamics
from planner.line import testing
from planner.line.model import G, Segments

REL = 1e-12  # pure arithmetic: only float round-off


def test_mass_and_effective_mass():
    m = dynamics.mass_kg(300e3, 100e3, np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(m, [300e3, 350e3, 400e3], rtol=REL)
    np.testing.assert_allclose(dynamics.effective_mass_kg(m, 0.08), m * 1.08, rtol=REL)
    tt = testing.train_type(rotating_mass_factor=0.1)
    assert tt.effective_mass_kg(0.5) == pytest.approx(350e3 * 1.1, rel=REL)


def test_tractive_effort_interpolates_and_scales():
    sp = np.array([0.0, 10.0, 20.0])
    ef = np.array([300e3, 300e3, 100e3])
    f = dynamics.tractive_effort_N(np.array([5.0, 15.0, 20.0]), sp, ef, 0.9)
    np.testing.assert_allclose(f, [270e3, 180e3, 90e3], rtol=REL)


def test_davis_resistance():
    # R = A + B v + C v²: 2000 + 50*10 + 3*100
    assert dynamics.davis_resistance_N(10.0, 2000.0, 50.0, 3.0) == pytest.approx(2800.0, rel=REL)


def test_gradient_and_curve_forces():
    assert dynamics.gradient_force_N(1000.0, 0.01) == pytest.approx(1000 * G * 0.01, rel=REL)
    # 800/R N per kN of weight, R = 400 m → 2 N/kN → 0.002 N/N
    spec = dynamics.curve_specific_resistance(
        Segments(np.array([0.0]), np.array([1000.0]), np.array([400.0])), np.array([500.0]), 100.0, 1)
    np.testing.assert_allclose(spec, [0.002], rtol=REL)


def _overlap_mean(starts, ends, vals, lo, hi):
    """Independent reference: overlap of [lo, hi] with each segment, summed."""
    tot = 0.0
    for a, b, q in zip(starts, ends, vals):
        tot += q * max(0.0, min(b, hi) - max(a, lo))
    return tot / (hi - lo)


@settings(max_examples=60, deadline=None)
@given(
    cuts=st.lists(st.floats(0, 2000), min_size=2, max_size=8, unique=True),
    vals=st.lists(st.floats(-0.04, 0.04), min_size=8, max_size=8),
    front=st.floats(-200, 2200),
    length=st.floats(10, 400),
    direction=st.sampled_from([1, -1]),
)
def test_mean_over_train_matches_overlap(cuts, vals, front, length, direction):
    c = np.sort(np.asarray(cuts))
    starts, ends = c[:-1], c[1:]
    # drop every other segment to leave gaps (level track)
    starts, ends = starts[::2], ends[::2]
    q = np.asarray(vals[: len(starts)])
    seg = Segments(starts, ends, q)
    got = dynamics.mean_over_train(seg, np.array([front]), length, direction)[0]
    lo, hi = (front - length, front) if direction == 1 else (front, front + length)
    assert got == pytest.approx(_overlap_mean(starts, ends, q, lo, hi), abs=1e-12)


def test_running_gradient_sign_flips_for_up():
    seg = Segments(np.array([0.0]), np.array([5000.0]), np.array([0.010]))  # 10 ‰ rising with chainage
    down = dynamics.running_gradient(seg, np.array([2000.0]), 100.0, 1)
    up = dynamics.running_gradient(seg, np.array([2000.0]), 100.0, -1)
    np.testing.assert_allclose(down, [0.010], rtol=REL)
    np.testing.assert_allclose(up, [-0.010], rtol=REL)


def test_gradient_averaged_over_train_entering_a_rise():
    # front 30 m into a 10 ‰ rise, train 100 m long: 30 % of the train on the rise
    seg = Segments(np.array([1000.0]), np.array([3000.0]), np.array([0.010]))
    g = dynamics.running_gradient(seg, np.array([1030.0]), 100.0, 1)
    np.testing.assert_allclose(g, [0.003], rtol=1e-12)


def test_track_accel_independent_of_load():
    # −g (grad + curve) / (1 + ρ): M g ḡ / (M (1+ρ))
    a = dynamics.track_accel_ms2(0.01, 0.002, 0.1)
    assert a == pytest.approx(-G * 0.012 / 1.1, rel=REL)


def test_acceleration_cap_reduces_traction_only():
    # full notch would give 2 m/s², the cap is 1 m/s²
    a = dynamics.acceleration_ms2(10.0, 2e5, 0.0, 1e-5, 0.0, 1.0)
    assert a == pytest.approx(1.0)
    # steep fall: coasting alone gives 1.5 m/s² > cap; the cap cannot brake
    a = dynamics.acceleration_ms2(10.0, 2e5, 0.0, 1e-5, 1.5, 1.0)
    assert a == pytest.approx(1.5)
    # below the cap: (F − R)/M_e + a_track
    a = dynamics.acceleration_ms2(10.0, 5e4, 1e4, 1e-5, -0.1, 1.0)
    assert a == pytest.approx(0.4 - 0.1)
