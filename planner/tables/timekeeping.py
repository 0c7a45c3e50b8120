"""Time-keeping driver support: the cruise speed that arrives on time (docs/design.md §4).

A continuous on-board support method, an alternative to the ratio tables of
§3: from the remaining time t_d and remaining distance x_d, and the stopping
deceleration β, compute the constant cruise speed v_m that reaches the stop
marker exactly at the scheduled arrival, and re-compute it as the train runs
and whenever the traffic-control centre moves the scheduled arrival.

The pure target-speed functions are in :mod:`planner.tables.cruise`. Here is
the on-board logic (:class:`TimekeepingController`): a controller of the one
integrator, :func:`planner.physics.run_curve.simulate`, that sees only the
vehicle's own nominal model and its measurements; :func:`drive` runs one train
with it (the plant: the real train's load and traction), and
:func:`closed_loop_runner` the designated-time sweep of ``planner simulate
--mode timekeeping``, with scheduled-arrival changes en route.

The single-run call with frames, :func:`planner.api.timekeeping_run`, sits on
top of :func:`drive`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.errors import InputError
from planner.tables.cruise import cruise_speed_limited


# --------------------------------------------------------------------------
# 2. The on-board logic: a controller of the one integrator
# --------------------------------------------------------------------------
ADVICE_NAMES = ("power", "hold", "coast", "brake")
"""Driver-support indication per sample (int8 codes index this tuple; they are
:mod:`planner.physics.run_curve`'s phase codes, with ``stop`` shown as ``brake``)."""

RECOMPUTE_S = 5.0
"""Re-compute the target at least this often [s] ..."""
RECOMPUTE_M = 50.0
"""... and at least every this many metres [m] (whichever comes first)."""
TRIM_DECEL_MS2 = 0.2
"""Deceleration [m/s²] used to shed speed above the target where coasting alone
would slow the train less (level track with little resistance, falling gradient):
a light brake, so a later scheduled arrival is still kept. Comfortable, well
below the service brake."""
COAST_MIN_DECEL_MS2 = 0.05
"""Coasting counts as a way to shed speed only where it slows the train by at
least this much [m/s²]; weaker coasting would need kilometres."""
LEARN_MIN_STEPS = 10
"""Full-notch steps the vehicle measures before it trusts its fitted traction factor θ."""
LEARN_REPLAN_TOL = 0.005
"""Re-run the flat-out look-ahead when θ has moved by more than this since the last plan ..."""
LEARN_REPLAN_M = 200.0
"""... at most once every this many metres [m]."""
ACCEL_FLOOR_MS2 = 0.02
"""Below this full-notch acceleration [m/s²] the acceleration envelope is left
out of the target computation (the train holds its speed rather than gains)."""

GUIDE_TOL_MS2 = 0.01
"""Tolerance [m²/s²] on v² when the flat-out speed profile is thinned to the
nodes that matter (≈ 3e-4 m/s at 20 m/s: far below a 0.01 s effect on time)."""


def _compress_tol(s: np.ndarray, w: np.ndarray, tol: float):
    """Thin a sampled w(s) to a polyline within ``tol`` (Ramer–Douglas–Peucker).

    Exactly linear stretches (holding, constant-deceleration braking) keep
    only their ends; curved ones (powering) keep as many nodes as the
    tolerance needs.
    """
    n = len(s)
    if n <= 2:
        return s.copy(), w.copy()
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        x = s[i + 1:j]
        chord = w[i] + (w[j] - w[i]) * (x - s[i]) / (s[j] - s[i])
        dev = np.abs(w[i + 1:j] - chord)
        m = int(np.argmax(dev))
        if dev[m] > tol:
            keep[i + 1 + m] = True
            stack.append((i, i + 1 + m))
            stack.append((i + 1 + m, j))
    return s[keep], w[keep]


@dataclass(frozen=True)
class ChangeRecord:
    """A scheduled-arrival change as the run applied it.

    Attributes
    ----------
    at_s : float
        Time after departure the change was sent [s].
    applied_s : float
        Time it took effect (the first grid node at or after ``at_s``) [s].
    arrival_s : float
        New scheduled arrival [s after departure].
    earliest_s : float
        Earliest possible arrival from the state at ``applied_s`` (full
        performance to the ceiling, then the stop) [s after departure].
    shortfall_s : float
        max(0, earliest − scheduled) [s]: how late the train must be.
    """

    at_s: float
    applied_s: float
    arrival_s: float
    earliest_s: float
    shortfall_s: float


@dataclass(frozen=True)
class DriveResult:
    """Outcome of :func:`drive` (arrays on the track's grid, SI).

    Attributes
    ----------
    s_m, t_s, v_ms, target_ms : ndarray
        Running distance [m], time after departure [s], speed [m/s] and the
        target the driver is shown [m/s] at every grid node.
    advice : ndarray of int8
        Index into :data:`ADVICE_NAMES` for the step arriving at each node
        (the first node repeats the first step's).
    time_s : float
        Arrival at the stop (speed zero) [s after departure].
    scheduled_s : float
        Scheduled arrival in force at the end [s after departure].
    stop_m : float
        Running distance where the train came to a stand [m].
    length_m : float
        Distance to the stop marker [m].
    shortfall_s : float
        Predicted lateness when the last scheduled arrival could not be met
        (see :class:`ChangeRecord`); 0 when it could.
    changes : tuple of ChangeRecord
        The departure schedule first (``at_s`` = 0), then every change.
    recomputes : int
        How many times the target was re-computed.
    """

    s_m: np.ndarray
    t_s: np.ndarray
    v_ms: np.ndarray
    target_ms: np.ndarray
    advice: np.ndarray
    time_s: float
    scheduled_s: float
    stop_m: float
    length_m: float
    shortfall_s: float
    changes: tuple
    recomputes: int

    @property
    def arrival_error_s(self) -> float:
        """Actual − scheduled arrival [s] (positive: late)."""
        return self.time_s - self.scheduled_s

    @property
    def stop_error_m(self) -> float:
        """Stop position − stop marker [m] (positive: overrun)."""
        return self.stop_m - self.length_m

    @property
    def feasible(self) -> bool:
        """True if the final scheduled arrival could be kept."""
        return self.shortfall_s <= 0.0


class TimekeepingController:
    """The time-keeping on-board logic (docs/design.md §4) as a controller of :func:`planner.physics.run_curve.simulate`.

    It knows what a vehicle knows: the track from its DB, its **own nominal
    model** of the train (``model`` at ``model_load`` and ``model_traction``),
    and at each decision node what it measures (position, time since
    departure, speed). The real train, the plant, is whatever ``simulate`` runs
    (its load and traction factor); the controller never sees them, so a
    heavier or weaker train than the model shows up as lateness it corrects.

    At departure, at every decision node and at once when a change of the
    scheduled arrival takes effect, it computes the cruise speed v_m with
    :func:`cruise_speed_limited` from the remaining time and distance under
    its model's flat-out speed profile (full power, braking only for the
    on-board ceiling), including the acceleration envelope from the current
    speed and the gentlest way down to a lower speed (coasting where it slows
    the train noticeably, a light trim brake, the service brake). The
    vehicle then runs at ratio 1.0 under the cap v_m: power below it, hold at
    it (constant-speed control; sawtooth vehicles run their coasting band
    below it), shed speed at the planned deceleration above it (following a
    restriction's braking curve at the service brake where that is lower,
    as the target computation assumes), and brake
    onto the marker on the stopping curve, after which the stop is committed
    and later changes are recorded but cannot re-plan it.

    Whenever the schedule is set (departure and each change) the model is
    run flat out from the measured state (the same integrator) for the
    earliest arrival; a scheduled arrival earlier than that is a shortfall,
    reported, and the run goes flat out: never silently missed.

    The vehicle learns how far its real performance is from its model, as a
    driver does in the first seconds of a run: on every full-notch step it
    compares the measured acceleration with what the model predicts, and
    fits a traction factor θ (least squares over all such steps, tractive
    part only: gradient and curve act the same on any load) that folds its
    unknown load and catenary voltage into one number. When θ has moved by
    more than :data:`LEARN_REPLAN_TOL` since the last plan (at most every
    :data:`LEARN_REPLAN_M`), the flat-out look-ahead is re-run with it, so a
    heavier or weaker train than the model plans with what it really has.
    Steps at the acceleration cap tell nothing about θ and are skipped.

    Parameters
    ----------
    track : planner.physics.track.Track
    model : planner.line.model.TrainType
        The vehicle's own model of itself (the track's train type).
    arrival_s : float or ndarray (n,)
        Scheduled arrival of each run [s after departure].
    changes : sequence of (at_s, arrival_s)
        For every run: at ``at_s`` s after departure the scheduled arrival
        becomes ``arrival_s`` s after departure.
    model_load, model_traction : float
        The conditions the model assumes (nominal: empty, full traction).
    recompute_s, recompute_m : float
        Re-computation period [s] and spacing [m], whichever comes first.

    Every grid node is a decision node (``decision_m``), so a change of the
    scheduled arrival takes effect within one grid step (≈ 0.05 s at speed);
    at nodes where nothing is due the controller returns None (no change).
    """

    def __init__(self, track, model, arrival_s, changes=(), *, model_load: float = 0.0,
                 model_traction: float = 1.0, recompute_s: float = RECOMPUTE_S,
                 recompute_m: float = RECOMPUTE_M):
        from planner.physics import dynamics, speed_profile

        if model.train_type != track.train_type:
            raise InputError(f"track is for train type {track.train_type!r}, not {model.train_type!r}")
        if not (recompute_m > 0 and recompute_s > 0):
            raise InputError(f"re-computation every {recompute_s} s / {recompute_m} m: both must be > 0")
        arrival = np.atleast_1d(np.asarray(arrival_s, dtype=float)).copy()
        for a in arrival:
            _check_schedule(float(a), ())
        self.track, self.model = track, model
        self.model_load, self.model_traction = float(model_load), float(model_traction)
        self.changes = _check_schedule(float(arrival[0]), changes)
        s = np.asarray(track.s_m, dtype=float)
        self.s = s
        self.decision_m = s[:-1].tolist()
        self._k = {x: i for i, x in enumerate(self.decision_m)}
        self.recompute_s, self.recompute_m = float(recompute_s), float(recompute_m)
        self.beta = float(model.stop_brake_ms2)
        self.service = float(model.service_brake_ms2)
        self.stop2 = speed_profile.stop_curve_sq(s, track.length_m, model.stop_brake_ms2)
        m = dynamics.mass_kg(model.empty_mass_kg, model.full_load_mass_kg, self.model_load)
        self._inv_me = 1.0 / float(dynamics.effective_mass_kg(m, model.rotating_mass_factor))
        self._ag = dynamics.track_accel_ms2(track.gradient, track.curve_specific, model.rotating_mass_factor)
        self.sawtooth = model.cruise == "sawtooth"
        n = arrival.size
        self.arrival = arrival
        self.next_change = np.zeros(n, dtype=int)
        self.next_at = np.full(n, self.changes[0][0] if self.changes else np.inf)
        self.next_t = np.full(n, -np.inf)
        self.next_s = np.full(n, -np.inf)
        self.flat_out = np.zeros(n, dtype=bool)
        self.committed = np.zeros(n, dtype=bool)
        self.cap = np.full(n, np.inf)
        self.shed = np.full(n, self.service)
        self.recomputes = np.zeros(n, dtype=int)
        self.records: list[list[ChangeRecord]] = [[] for _ in range(n)]
        self.guides: list = [None] * n
        # learning θ: least-squares sums, the θ of the last plan, where the next re-plan may come
        self.theta = np.full(n, self.model_traction)
        self.theta_plan = self.theta.copy()
        self._sxy, self._sxx = np.zeros(n), np.zeros(n)
        self._n_fit = np.zeros(n, dtype=int)
        self.next_replan_s = np.zeros(n)
        self._prev = None  # (node, speeds) of the previous call

    # -- the vehicle's own model, one speed at a time ----------------------------
    def _accel(self, v: float, k: int, theta: float) -> tuple[float, float]:
        """Full-notch and coasting acceleration of the model at speed v, node k, traction θ [m/s²]."""
        from planner.physics import dynamics

        md = self.model
        res = float(dynamics.davis_resistance_N(v, md.davis_a_N, md.davis_b_N_per_ms, md.davis_c_N_per_ms2))
        eff = float(dynamics.tractive_effort_N(v, md.traction_speed_ms, md.traction_effort_N, theta))
        full = float(dynamics.acceleration_ms2(v, eff, res, self._inv_me, self._ag[k], md.max_accel_ms2))
        return full, float(self._ag[k]) - res * self._inv_me

    def _learn(self, k: int, state) -> None:
        """Fit θ from the full-notch step that arrived at node k (class doc)."""
        from planner.physics import dynamics
        from planner.physics.run_curve import PHASE_POWER

        prev, self._prev = self._prev, (k, state.v_ms.copy())
        if prev is None or prev[0] != k - 1:
            return
        v0, v1 = prev[1], state.v_ms
        md = self.model
        a_meas = (v1 * v1 - v0 * v0) / (2.0 * (self.s[k] - self.s[k - 1]))
        ok = (state.phase == PHASE_POWER) & (a_meas < md.max_accel_ms2 - 1e-3) & (v0 > 0.0)
        if not ok.any():
            return
        parts = []
        for v, j in ((v0, k - 1), (v1, k)):
            f = dynamics.tractive_effort_N(v, md.traction_speed_ms, md.traction_effort_N) * self._inv_me
            r = dynamics.davis_resistance_N(v, md.davis_a_N, md.davis_b_N_per_ms, md.davis_c_N_per_ms2)
            parts.append((f, self._ag[j] - r * self._inv_me))
        a_f = 0.5 * (parts[0][0] + parts[1][0])
        a_rest = 0.5 * (parts[0][1] + parts[1][1])
        ok &= a_f > 1e-3
        self._sxy += np.where(ok, a_f * (a_meas - a_rest), 0.0)
        self._sxx += np.where(ok, a_f * a_f, 0.0)
        self._n_fit += ok
        fit = self._n_fit >= LEARN_MIN_STEPS
        self.theta = np.where(fit, self._sxy / np.where(fit, self._sxx, 1.0), self.theta)

    # -- planning: the earliest arrival and the limit profile --------------------
    def _plan(self, k: int, runs: np.ndarray, state, at_s: np.ndarray | None) -> None:
        """Run the model flat out from the measured state of ``runs`` (the one integrator).

        ``at_s`` the times the schedule was set (recorded as :class:`ChangeRecord`);
        None for a re-plan after learning θ (not a schedule event).
        """
        from planner.physics.run_curve import RunState, simulate

        t, v, ph = state.t_s[runs], state.v_ms[runs], state.phase[runs]
        # flat out powers from here: a sawtooth run in its coasting band does too once commanded
        # faster (simulate ends its coasting), so the look-ahead does not coast on in the band either
        start = RunState(np.full(runs.size, self.s[k]), t, v, ph, np.ones(runs.size),
                         coasting=np.zeros(runs.size, dtype=bool))
        res = simulate(self.track, self.model, 1.0, load=self.model_load, traction_factor=self.theta[runs],
                       start=start, record=True)
        self.theta_plan[runs] = self.theta[runs]
        for j, i in enumerate(runs.tolist()):
            earliest = float(res.time_s[j])
            short = max(0.0, earliest - self.arrival[i])
            if at_s is not None:
                self.records[i].append(ChangeRecord(float(at_s[j]), float(t[j]), float(self.arrival[i]),
                                                    earliest, short))
            self.flat_out[i] = short > 0.0
            self.guides[i] = _compress_tol(res.s_m, np.square(res.v_ms[j]), GUIDE_TOL_MS2)

    def _target(self, i: int, k: int, t: float, v: float) -> None:
        gs, gw = self.guides[i]
        s0 = self.s[k]
        j = int(np.searchsorted(gs, s0, side="right"))
        s_sub = np.concatenate([[s0], gs[j:]])
        w_sub = np.concatenate([[max(float(np.interp(s0, gs, gw)), v * v)], gw[j:]])
        if s_sub.size < 2:
            return
        a0, coast = self._accel(v, k, float(self.theta[i]))
        dc = -coast
        d_trim = max(TRIM_DECEL_MS2, dc)
        decels = ((dc,) if dc >= COAST_MIN_DECEL_MS2 else ()) + (d_trim, max(d_trim, self.service))
        tg = cruise_speed_limited(self.arrival[i] - t, s_sub, np.sqrt(np.maximum(w_sub, 0.0)), self.beta,
                                  v0_ms=v, accel_ms2=a0 if a0 > ACCEL_FLOOR_MS2 else None, decel_ms2=decels)
        self.recomputes[i] += 1
        if not tg.feasible:
            self.cap[i], self.shed[i] = np.inf, self.service
            return
        cap = float(tg.speed_ms)
        if self.sawtooth:
            # a vehicle without constant-speed control coasts down its band below the cap and
            # powers back up: its mean speed is about the band's middle, so aim the band there
            cap += 0.5 * self.model.coast_band_ms
        self.cap[i] = cap
        self.shed[i] = float(tg.decel_ms2) if math.isfinite(tg.decel_ms2) else self.service

    def _onto_braking_curve(self, k: int, v: np.ndarray) -> np.ndarray:
        """Runs shedding gently onto their cap whose next step would end above a braking curve of the
        ceiling (a restriction's service-brake curve, as in the flat-out guide): they follow it at the
        service brake from here, as the target computation assumes (``min(shed line, ceiling)``).

        The integrator sheds at the controller's rate whenever a run is above its ceiling, whatever
        lowered it, so a trim meant for the cap would run on above a braking curve that falls faster
        (found in the closed loop at 1 s steps: E8 down MDR→TKD at 173 s, plant at full load and
        traction × 0.9, ran 38 m above a restriction's curve and arrived 1.12 s early)."""
        out = np.zeros(v.size, dtype=bool)
        if k + 1 >= self.s.size:
            return out
        s0, s1 = self.s[k], self.s[k + 1]
        for i in np.flatnonzero(~self.committed & (self.shed < self.service) & (v > self.cap)).tolist():
            gs, gw = self.guides[i]
            g0, g1 = np.interp([s0, s1], gs, gw)
            out[i] = g1 < g0 and v[i] * v[i] - 2.0 * self.shed[i] * (s1 - s0) > g1 + GUIDE_TOL_MS2
        return out

    def __call__(self, s_m: float, state):
        from planner.physics.run_curve import Command

        k = self._k[s_m]
        t, v = state.t_s, state.v_ms
        n = t.size
        plan = np.zeros(n, dtype=bool)
        at = np.zeros(n)
        if k == 0 and not self.records[0]:
            plan[:] = True
        # scheduled-arrival changes take effect at the first node at or after their time
        for i in np.flatnonzero(t >= self.next_at - 1e-12).tolist():
            while self.next_change[i] < len(self.changes) and t[i] >= self.changes[self.next_change[i]][0] - 1e-12:
                c_at, c_arr = self.changes[self.next_change[i]]
                self.next_change[i] += 1
                self.arrival[i] = c_arr
                if self.committed[i]:
                    # already braking onto the marker: the stop cannot be re-planned
                    self.records[i].append(ChangeRecord(c_at, float(t[i]), c_arr, math.nan, math.nan))
                else:
                    plan[i], at[i] = True, c_at
            nc = self.next_change[i]
            self.next_at[i] = self.changes[nc][0] if nc < len(self.changes) else np.inf
        if plan.any():
            self._plan(k, np.flatnonzero(plan), state, at[plan])
        self._learn(k, state)
        replan = (~plan & ~self.committed & (np.abs(self.theta - self.theta_plan) > LEARN_REPLAN_TOL)
                  & (s_m >= self.next_replan_s))
        if replan.any():
            self._plan(k, np.flatnonzero(replan), state, None)
            self.next_replan_s[replan] = s_m + LEARN_REPLAN_M
            plan |= replan
        newly = np.zeros(n, dtype=bool)
        if k > 0:
            # on the stopping curve: the stop is committed, the curve alone governs
            newly = ~self.committed & (v * v >= self.stop2[k] - 1e-9)
            self.committed |= newly
        due = plan | ((t >= self.next_t) | (s_m >= self.next_s)) & ~self.committed & ~self.flat_out
        for i in np.flatnonzero(due | newly).tolist():
            if self.committed[i] or self.flat_out[i]:
                self.cap[i], self.shed[i] = np.inf, self.service
            else:
                self._target(i, k, float(t[i]), float(v[i]))
                self.next_t[i], self.next_s[i] = t[i] + self.recompute_s, s_m + self.recompute_m
        curve = self._onto_braking_curve(k, v)
        self.shed[curve] = self.service
        if not (due.any() or newly.any() or curve.any()):
            return None
        return Command(np.ones(n), self.cap.copy(), self.shed.copy())


def _check_schedule(arrival_s: float, changes) -> list[tuple[float, float]]:
    """Validate the scheduled arrival and the changes; return changes sorted by time."""
    if not (isinstance(arrival_s, (int, float, np.floating)) and math.isfinite(arrival_s) and arrival_s > 0):
        raise InputError(f"scheduled arrival must be a positive number of seconds after departure, "
                         f"got {arrival_s!r} (--arrival)")
    out = []
    for i, ch in enumerate(changes):
        try:
            at, new = (float(x) for x in ch)
        except (TypeError, ValueError):
            raise InputError(f"change {i} must be (seconds after departure, new arrival), got {ch!r} "
                             "(--change T:ARRIVAL)") from None
        if not (math.isfinite(at) and math.isfinite(new) and at >= 0.0 and new > 0.0):
            raise InputError(f"change {i} ({at:g}:{new:g}) needs a time ≥ 0 and a new arrival > 0 "
                             "seconds after departure (--change T:ARRIVAL)")
        out.append((at, new))
    return sorted(out, key=lambda c: c[0])


def drive(track, train, arrival_s: float, *, changes=(), load: float = 0.0,
          traction_factor: float = 1.0, recompute_s: float = RECOMPUTE_S, recompute_m: float = RECOMPUTE_M,
          model_load: float = 0.0, model_traction: float = 1.0) -> DriveResult:
    """One train driven by the time-keeping logic in the one integrator (docs/design.md §4).

    The on-board logic is a :class:`TimekeepingController` with the vehicle's
    nominal model of itself (``model_load``, ``model_traction``); the plant is
    the real train at ``load`` and ``traction_factor``, run by
    :func:`planner.physics.run_curve.simulate` (the same run-curve physics as every
    table). See the controller for what the logic does.

    Parameters
    ----------
    track : planner.physics.track.Track
    train : planner.line.model.TrainType
        Must be ``track``'s train type.
    arrival_s : float
        Scheduled arrival [s after departure].
    changes : sequence of (at_s, arrival_s)
        At ``at_s`` seconds after departure the scheduled arrival becomes
        ``arrival_s`` seconds after departure.
    load, traction_factor : float
        Load factor and tractive-effort multiplier of the real train.
    recompute_s, recompute_m : float
        Re-computation period [s] and spacing [m] of the target.
    model_load, model_traction : float
        What the on-board model assumes (nominal by default).

    Returns
    -------
    DriveResult
    """
    from planner.physics.run_curve import PHASE_BRAKE, PHASE_STOP, simulate

    if train.train_type != track.train_type:
        raise InputError(f"track is for train type {track.train_type!r}, not {train.train_type!r}")
    if not (load >= 0.0 and traction_factor > 0.0):
        raise InputError(f"load must be ≥ 0 and traction factor > 0, got {load} and {traction_factor}")
    ctl = TimekeepingController(track, train, float(arrival_s), changes, model_load=model_load,
                                model_traction=model_traction, recompute_s=recompute_s, recompute_m=recompute_m)
    res = simulate(track, train, 1.0, load=float(load), traction_factor=float(traction_factor),
                   controller=ctl, decision_m=ctl.decision_m, record=True)
    t_end = float(res.time_s[0])
    # changes that came while braking onto the marker could not re-plan the stop:
    # the earliest arrival was the committed one
    records = [r if math.isfinite(r.earliest_s) else
               ChangeRecord(r.at_s, r.applied_s, r.arrival_s, t_end, max(0.0, t_end - r.arrival_s))
               for r in ctl.records[0]]
    phase = res.phase[0]
    advice = np.where(phase == PHASE_STOP, PHASE_BRAKE, phase).astype(np.int8)
    c2 = track.ceiling_sq(1.0, train)[0]
    target = np.sqrt(np.minimum(np.square(res.cap_ms[0]), c2[-res.s_m.size:]))
    return DriveResult(
        s_m=res.s_m.copy(), t_s=res.t_s[0], v_ms=res.v_ms[0], target_ms=target, advice=advice, time_s=t_end,
        scheduled_s=float(records[-1].arrival_s), stop_m=float(res.stop_m[0]), length_m=float(track.length_m),
        shortfall_s=float(records[-1].shortfall_s), changes=tuple(records), recomputes=int(ctl.recomputes[0]))


def closed_loop_runner(track, train, tables, designated_s, sc, mode="timekeeping"):
    """The ``timekeeping`` mode of :mod:`planner.tables.closed_loop` (``planner simulate --mode timekeeping``).

    Every designated running time of the sweep in one batch of the integrator:
    the on-board logic with the vehicle's nominal model (no tables needed: the
    target comes from the remaining time and distance), the plant under the
    scenario's load and traction.

    Returns
    -------
    actual_s : ndarray (n,)
        Simulated running times [s].
    ratios : ndarray (n, n_x)
        NaN: this mode chooses no ratios (shape as the table modes' for the datasets).
    stop_m : ndarray (n,)
        Where each run came to a stand [m of running distance].
    """
    from planner.physics.run_curve import simulate

    designated = np.asarray(designated_s, dtype=float).reshape(-1)
    ctl = TimekeepingController(track, train, designated)
    res = simulate(track, train, np.ones_like(designated), load=sc.load, traction_factor=sc.traction_factor,
                   controller=ctl, decision_m=ctl.decision_m)
    n_x = len(getattr(tables, "eval_point_ids", ()))
    return np.asarray(res.time_s, float), np.full((designated.size, n_x), np.nan), np.asarray(res.stop_m, float)
