"""Train dynamics: the forces of classic running theory, as pure numpy functions.

Every function takes floats or numpy arrays (broadcast together) in SI units
and returns the same; nothing here reads files or builds DataFrames, so the
integrator in :mod:`planner.physics.run_curve` can call them on whole batches of runs.

The model (docs/design.md §2)::

    M   = empty mass + load × full passenger mass                  [kg]
    M_e = M (1 + rotating-mass factor)                             [kg]
    F(v) = interp(traction curve)(v) × traction factor             [N]
    R(v) = A + B v + C v²  (Davis)                                 [N]
    F_g  = M g ḡ            ḡ = gradient averaged over the train    [N]
    F_c  = M g (800/R)/1000 × fraction of the train in the curve   [N]
    a    = min((F − R − F_g − F_c) / M_e, a_max)                    [m/s²]

Gradient and curve forces are proportional to the static mass M, inertia to
M_e, so their acceleration ``−g (ḡ + r_c) / (1 + ρ)`` does not depend on the
load; :func:`track_accel` computes it once per grid node and the batch shares it.
"""
from __future__ import annotations

import numpy as np

from planner.line.model import G, Segments

CURVE_RESISTANCE_N_PER_KN_M = 800.0
"""Curve resistance coefficient: ``800/R`` N per kN of train weight, R in metres
(the classic Japanese running-time formula for standard and narrow gauge)."""


def mass_kg(empty_mass_kg, full_load_mass_kg, load):
    """Static train mass ``M = empty + load × full passenger mass`` [kg]."""
    return empty_mass_kg + np.asarray(load, dtype=float) * full_load_mass_kg


def effective_mass_kg(mass, rotating_mass_factor):
    """Inertial mass ``M_e = M (1 + ρ)`` [kg] (rotating parts add inertia, not weight)."""
    return mass * (1.0 + rotating_mass_factor)


def tractive_effort_N(v_ms, speed_ms, effort_N, traction_factor=1.0):
    """Full-notch tractive effort of the whole train [N].

    Linear interpolation of the traction curve (``speed_ms`` strictly increasing,
    ``effort_N`` ≥ 0) times ``traction_factor`` (1.0 nominal, 0.9 for a weak
    catenary). Outside the curve the end values hold; line validation guarantees
    the curve covers 0 … vehicle maximum speed.
    """
    return np.interp(v_ms, speed_ms, effort_N) * traction_factor


def davis_resistance_N(v_ms, a_N, b_N_per_ms, c_N_per_ms2):
    """Running resistance ``R(v) = A + B v + C v²`` [N] (Davis form, v in m/s)."""
    return a_N + v_ms * (b_N_per_ms + c_N_per_ms2 * v_ms)


def gradient_force_N(mass, gradient):
    """Gradient resistance ``M g ḡ`` [N]; ``gradient`` is rise per metre in the running direction."""
    return mass * G * gradient


def curve_resistance_N(mass, curve_specific):
    """Curve resistance [N] from the specific resistance ``(800/R)/1000 × fraction in curve``."""
    return mass * G * curve_specific


def mean_over_train(segments: Segments, front_m, length_m: float, direction_sign: int,
                    transform=None):
    """Mean of a piecewise-constant quantity over the train's length [same unit].

    The train's front is at chainage ``front_m`` and its body extends
    ``length_m`` behind it (towards smaller chainage for ``down``,
    ``direction_sign`` = +1; larger for ``up``, −1). Gaps between segments count
    as zero (level, straight). Uses the exact cumulative integral
    ``I(x) = ∫ q dx``, piecewise linear in x, so the mean is
    ``(I(hi) − I(lo)) / length``.

    Parameters
    ----------
    segments : Segments
        Chainage segments and their values.
    front_m : ndarray
        Chainage of the train's front [m].
    length_m : float
        Train length [m], > 0.
    direction_sign : int
        +1 (down) or −1 (up).
    transform : callable, optional
        Applied to ``segments.value`` first (e.g. radius → 0.8/R).
    """
    front = np.asarray(front_m, dtype=float)
    if len(segments) == 0:
        return np.zeros_like(front)
    q = segments.value if transform is None else transform(segments.value)
    knots = np.concatenate([segments.start_m, segments.end_m])
    order = np.argsort(knots, kind="stable")
    knots = knots[order]
    # slope change at every start (+q) and end (−q); I is the running integral.
    dq = np.concatenate([q, -q])[order]
    slope = np.cumsum(dq)[:-1]
    integral = np.concatenate([[0.0], np.cumsum(slope * np.diff(knots))])
    tail = front - direction_sign * length_m
    lo, hi = np.minimum(front, tail), np.maximum(front, tail)
    return (np.interp(hi, knots, integral) - np.interp(lo, knots, integral)) / length_m


def running_gradient(segments: Segments, front_m, length_m: float, direction_sign: int):
    """Gradient [rise/m] averaged over the train, positive when rising in the running direction.

    Gradients are stored positive when rising towards increasing chainage, so a
    train running ``up`` (sign −1) sees them with the sign flipped.
    """
    return direction_sign * mean_over_train(segments, front_m, length_m, direction_sign)


def curve_specific_resistance(segments: Segments, front_m, length_m: float, direction_sign: int):
    """Specific curve resistance [N/N] over the train: ``Σ (800/R_i)/1000 × fraction in curve i``."""
    return mean_over_train(segments, front_m, length_m, direction_sign,
                           transform=lambda r: CURVE_RESISTANCE_N_PER_KN_M / r / 1000.0)


def track_accel_ms2(gradient, curve_specific, rotating_mass_factor: float):
    """Acceleration from gradient and curve resistance [m/s²]: ``−g (ḡ + r_c) / (1 + ρ)``.

    Independent of load because both forces scale with M and inertia with M(1+ρ).
    """
    return -G * (np.asarray(gradient) + np.asarray(curve_specific)) / (1.0 + rotating_mass_factor)


def acceleration_ms2(v_ms, tractive_N, resistance_N, inv_effective_mass, track_accel, max_accel_ms2):
    """Net acceleration under full notch, capped at the vehicle's maximum [m/s²].

    ``a = min((F − R)/M_e + a_track, max(a_max, a_coast))``: the cap reduces
    traction only, so on a steep fall where gravity alone exceeds ``a_max`` the
    train runs at its coasting acceleration (braking to hold speed is the
    ceiling's job, not the cap's).
    """
    coast = track_accel - resistance_N * inv_effective_mass
    full = coast + tractive_N * inv_effective_mass
    return np.minimum(full, np.maximum(max_accel_ms2, coast))
