"""Run curves: the distance-domain, lock-step batch integrator (DESIGN §2, §3).

A *run* is one train running from a departure stop marker to the next stop
marker at a target-speed ratio. A *batch* advances many runs (different ratios,
loads, traction factors, start states, ratio changes) together over the same
grid of running distance ``s`` [m], so every per-position look-up (on-board
maximum, gradient, curve, ceiling) is an index, and evaluation points are exact
grid nodes.

The method
----------
Work in ``w = v²`` against distance, where constant acceleration is linear:

* **free running** (power below the target, or coast for sawtooth vehicles):
  Heun's second-order step ``w₁ = w₀ + (a(v₀, s₀) + a(ṽ₁, s₁)) Δs`` with the
  predictor ``ṽ₁² = w₀ + 2 a(v₀, s₀) Δs``;
* **ceiling** ``c²(s) = min(target², service-brake curves to every lower
  target ahead, stopping-brake curve onto the marker)`` (see
  :mod:`planner.physics.speed_profile`): linear in ``w`` between nodes, so holding the
  target and braking along a curve are exact;
* a step that meets the ceiling inside it is **split** at the crossing (the
  root of the linear gap ``w − c²``): free running up to it, the ceiling after;
  a lowered ratio leaves the train above the new ceiling, and it brakes at the
  service brake (``w`` falls by ``2 b Δs``) until it meets it, split alike;
  (where the ceiling rises inside that step, as a restriction's tail clears,
  the train runs free from the crossing, capped by the ceiling, rather than
  riding up the ceiling faster than it can accelerate);
* a sawtooth vehicle coasts from the point where it meets a level or falling
  ceiling, and the band's lower edge splits a coasting step the same way, so
  the coasting cycles do not snap to grid nodes (that would be first order);
* time over a piece of constant acceleration is ``Δt = 2 Δs / (v₀ + v₁)``,
  exact, with no singularity when starting from standstill.

Errors are second order in the step; the tests show running times within
0.05 s of closed-form answers at the default 1 m and converged under step
halving. The final node is the arrival marker, where the ceiling is zero, so
every run ends standing exactly at ``length_m``.

A run's *phase* at a node (``PHASE_*``) is what it did on the step that
arrived there; a start state with any phase but power puts a sawtooth vehicle
in its coasting band, so a run continued from a snapshot repeats the original.

The loop is :class:`_Integrator`, one method per step above (events and the
controller hook, free running, ceiling and brake, sawtooth band, phase codes,
recording); it is the one integrator: the tables, the closed loop of every
on-board mode (the ratio modes and the time-keeping mode, through
:class:`Command`), the margins and the run-curve API all run through it.

Energy is the mechanical traction work at the wheel ``∫ F ds`` while F > 0
(regenerative braking not credited), in kWh.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple, Sequence

import numpy as np

from planner.errors import InfeasibleError, InputError
from planner.line.model import TrainType
from planner.line.units import KWH
from planner.physics import dynamics, speed_profile
from planner.physics.track import NODE_TOL_M, Track

try:  # the compiled kernel behind np.interp, without its per-call Python checks (~2 µs)
    from numpy._core.multiarray import interp as _interp
except ImportError:  # pragma: no cover - other numpy layouts
    _interp = np.interp

PHASE_POWER, PHASE_HOLD, PHASE_COAST, PHASE_BRAKE, PHASE_STOP = 0, 1, 2, 3, 4
PHASE_NAMES = ("power", "hold", "coast", "brake", "stop")

SAWTOOTH_MIN_FRACTION = 0.5
"""A sawtooth vehicle coasts down to ``max(target − band, 0.5 × target)``: at low
targets a full band would coast to a crawl (or a standstill on a rise)."""


@dataclass(frozen=True)
class RunState:
    """State of n runs at one grid node; every array has shape (n,).

    Attributes
    ----------
    s_m : running distance [m]; t_s : time since departure [s]; v_ms : speed [m/s];
    phase : int8 phase code of the step that arrived here (``PHASE_*``);
    ratio : target-speed ratio in force on that step.
    """

    s_m: np.ndarray
    t_s: np.ndarray
    v_ms: np.ndarray
    phase: np.ndarray
    ratio: np.ndarray


class Command(NamedTuple):
    """What an on-board controller asks of the runs at a decision node (each array shape (n,)).

    A controller (see :func:`simulate`) returns either a plain ratio array or a
    Command. The target is ``min(ratio × on-board maximum, cap_ms)``: the ratio
    modes of DESIGN §3 leave ``cap_ms`` at +inf; the time-keeping mode of §4
    runs at ratio 1.0 under a cruise-speed cap. A run above its new ceiling
    sheds speed at ``shed_ms2`` (default: the service brake) until it meets it.

    Attributes
    ----------
    ratio : ndarray
        Target-speed ratio, in (0, 1].
    cap_ms : ndarray, optional
        Cruise-speed cap [m/s] (+inf: none). Default: unchanged.
    shed_ms2 : ndarray, optional
        Deceleration [m/s²] (> 0) for getting down to a lowered target. Default: unchanged.
    """

    ratio: np.ndarray
    cap_ms: np.ndarray | None = None
    shed_ms2: np.ndarray | None = None


@dataclass(frozen=True)
class BatchResult:
    """Result of :func:`simulate` for n runs.

    ``time_s`` (n,) time at the stop marker [s] (same clock as the start state);
    ``energy_kwh`` (n,) traction work from the start [kWh]; ``snapshots`` the
    RunState at each requested position (taken before any change there).
    ``stop_m`` (n,) where each run came to a stand [m of running distance]: the
    arrival marker, or beyond it by the overrun if the last step asked more than
    the stopping brake gives (it never should: the stopping curve is in the ceiling).
    With ``record=True``: ``s_m`` (m,) the grid from the start node on, and
    ``t_s``, ``v_ms``, ``a_ms2`` (mean acceleration of the step arriving at the
    node; the first column repeats the first step's), ``phase``, ``ratio``,
    ``cap_ms`` (cruise cap in force, +inf where none), all (n, m).
    """

    time_s: np.ndarray
    energy_kwh: np.ndarray
    snapshots: dict
    stop_m: np.ndarray | None = None
    s_m: np.ndarray | None = None
    t_s: np.ndarray | None = None
    v_ms: np.ndarray | None = None
    a_ms2: np.ndarray | None = None
    phase: np.ndarray | None = None
    ratio: np.ndarray | None = None
    cap_ms: np.ndarray | None = None


class _Ceilings:
    """Per-run ceiling at any node without an (n, m) table.

    Between two changes of the on-board maximum the target is constant, so the
    backward recursion only matters at those change nodes ``K_e``: with
    ``E_e`` = service-brake ceiling at the end node of segment e,
    ``c²_k = min(r² V_k², E_e + 2 b (s_end(e) − s_k), 2 b_stop (L − s_k))`` for k in
    segment e. ``E`` (segments, n) costs a few operations per segment whenever
    the ratios change; a node's ceiling then costs five array operations.
    """

    def __init__(self, track: Track, train: TrainType):
        s, vi = track.s_m, track.vmax_interval_ms
        self.b2 = 2.0 * train.service_brake_ms2
        bounds = np.concatenate([[0], np.flatnonzero(np.diff(vi) != 0.0) + 1, [len(s) - 1]])
        self.bounds = bounds
        self.vn2 = track.vmax_ms ** 2
        seg = np.searchsorted(bounds, np.arange(len(s)), side="right") - 1  # segment starting at/containing k
        seg[-1] = len(bounds) - 1  # the arrival node: nothing ahead (column of +inf)
        self.seg = seg
        # 2b (s_end(e) − s_k) for each node, with s_end of the node's segment
        send = s[bounds[np.minimum(seg + 1, len(bounds) - 1)]]
        self.ahead = self.b2 * (send - s)
        self.stop2 = speed_profile.stop_curve_sq(s, track.length_m, train.stop_brake_ms2)

    def set(self, ratio: np.ndarray, cap2: np.ndarray) -> None:
        """Targets ``min(ratio² V², cap²)`` per run (``cap2`` = +inf where there is no cruise cap)."""
        self.r2 = ratio * ratio
        self.cap2 = cap2
        nb = len(self.bounds)
        e = np.empty((nb, len(ratio)))
        e[-1] = np.inf
        e[-2] = np.minimum(self.r2 * self.vn2[self.bounds[-1]], cap2)
        for j in range(nb - 3, -1, -1):
            kb = self.bounds[j + 1]
            e[j] = np.minimum(np.minimum(self.r2 * self.vn2[kb], cap2), e[j + 1] + self.ahead[kb])
        self.e = e

    def at(self, k: int) -> np.ndarray:
        target2 = np.minimum(self.r2 * self.vn2[k], self.cap2)
        return np.minimum(np.minimum(target2, self.e[self.seg[k]] + self.ahead[k]), self.stop2[k])


def _check_stall(t, track, train, load, tf, s_list, k_ok: int, k: int) -> None:
    """A run that stalled has a NaN or infinite time (v = sqrt(w ≤ 0)): say where, within the checked stretch."""
    bad = ~np.isfinite(t)
    if not np.count_nonzero(bad):
        return
    j = int(np.flatnonzero(bad)[0])
    a, b = sorted((float(track.position_m(s_list[k_ok])), float(track.position_m(s_list[k]))))
    raise InfeasibleError(
        f"train type {train.train_type} stalls on {track.origin}->{track.destination} between chainage "
        f"{a:.0f} and {b:.0f} m (run {j}: load {load[j]:g}, traction factor {tf[j]:g}): tractive effort "
        "cannot overcome resistance and gradient; check traction.parquet or the gradients")


def _as_batch(x, n: int, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise InputError(f"{name} must be a scalar or an array of shape ({n},), got shape {a.shape}")
    return a.copy()


def _check_ratio(r: np.ndarray, what: str) -> None:
    if not np.all((r > 0) & (r <= 1.0 + 1e-12)):
        bad = r[~((r > 0) & (r <= 1.0 + 1e-12))][0]
        raise InputError(f"{what} must lie in (0, 1], got {bad}")


def simulate(track: Track, train: TrainType, ratio, *, load=0.0, traction_factor=1.0,
             start: RunState | None = None,
             changes: Sequence[tuple[float, np.ndarray]] = (),
             controller: Callable[[float, RunState], np.ndarray] | None = None,
             decision_m: Sequence[float] = (),
             snapshots_m: Sequence[float] = (),
             record: bool = False) -> BatchResult:
    """Simulate a batch of runs to the arrival marker (module doc for the method).

    Parameters
    ----------
    track : Track
        From :func:`make_track` for ``train``'s type.
    train : TrainType
    ratio : float or ndarray (n,)
        Target-speed ratio from the start on, in (0, 1].
    load : float or ndarray (n,)
        Load factor (0 empty … 1 full).
    traction_factor : float or ndarray (n,)
        Multiplies the tractive-effort curve.
    start : RunState, optional
        Start state (all runs at the same grid node); default standing at s = 0,
        t = 0, powering. ``start.phase == PHASE_COAST`` lets a sawtooth vehicle
        carry on coasting. The ``ratio`` argument, not ``start.ratio``, is driven
        from the start; if the train is above its new ceiling it brakes.
    changes : sequence of (s_m, ratio (n,))
        Ratio changes at grid nodes; a lowered ratio brakes at the service brake
        until below the new target.
    controller : callable ``(s_m, state) -> ratio (n,) or Command or None``, optional
        Called at each ``decision_m`` node (after ``changes`` there). It sees
        what the vehicle measures (position, time, speed, phase) and returns
        the ratio, or a :class:`Command` with a cruise-speed cap and the
        deceleration for shedding speed (the time-keeping mode), or None
        for no change.
    decision_m, snapshots_m : sequence of float
        Grid nodes [m] for the controller and for returned states.
    record : bool
        Also return the whole curve of every run on the grid.

    Returns
    -------
    BatchResult

    Raises
    ------
    InfeasibleError
        If a run stalls (tractive effort cannot overcome resistance and gradient).
    """
    if train.train_type != track.train_type:
        raise InputError(f"track is for train type {track.train_type!r}, not {train.train_type!r}")
    sizes = [np.size(x) for x in (ratio, load, traction_factor) if np.ndim(x) > 0]
    if start is not None:
        sizes.append(np.size(start.v_ms))
    n = max(sizes) if sizes else 1
    ratio = _as_batch(ratio, n, "ratio")
    _check_ratio(ratio, "ratio")
    load = _as_batch(load, n, "load")
    tf = _as_batch(traction_factor, n, "traction_factor")
    if np.any(load < 0) or np.any(tf <= 0):
        raise InputError("load must be ≥ 0 and traction_factor > 0")
    if start is None:
        k0 = 0
        state = RunState(np.zeros(n), np.zeros(n), np.zeros(n), np.full(n, PHASE_POWER, dtype=np.int8), ratio)
    else:
        s0 = np.asarray(start.s_m, dtype=float).reshape(-1)
        if s0.size and np.ptp(s0) > NODE_TOL_M:
            raise InputError("all runs of a batch must start at the same running distance")
        k0 = track.node_index(float(s0[0]) if s0.size else 0.0)
        phase = np.asarray(start.phase, dtype=np.int8).reshape(-1).copy()
        if phase.shape != (n,):
            phase = np.full(n, phase.reshape(-1)[0] if phase.size else PHASE_POWER, dtype=np.int8)
        state = RunState(np.zeros(n), _as_batch(start.t_s, n, "start.t_s"), _as_batch(start.v_ms, n, "start.v_ms"),
                         phase, ratio)
    run = _Integrator(track, train, load, tf, state, k0, record)
    run.schedule(changes, controller, decision_m, snapshots_m)
    with np.errstate(divide="ignore", invalid="ignore"):
        run.run()
    return run.result()


class _Integrator:
    """One batch of runs through :func:`simulate`, one method per step of the method (module doc).

    The loop (:meth:`run`) advances every run from grid node k to k + 1: the
    events at k (:meth:`_events`: snapshots, ratio changes, the controller),
    then free running (:meth:`_free`, Heun's step under full notch or coasting),
    the ceiling and the service brake (:meth:`_guided`, split at the crossing),
    the sawtooth band (:meth:`_sawtooth`), the phase codes (:meth:`_phase`) and
    the recording (:meth:`_record`). Everything per run is an array of shape (n,).
    """

    def __init__(self, track: Track, train: TrainType, load: np.ndarray, tf: np.ndarray, state: RunState,
                 k0: int, record: bool):
        self.track, self.train, self.load, self.tf = track, train, load, tf
        s = track.s_m
        self.s, self.m, self.k0, self.n = s, len(s), k0, load.size
        n = self.n
        # the plant: per-run constants divided by M_e (the loop works in accelerations, and the
        # traction work per unit M_e follows from the energy balance of each piece)
        self.inv_me = 1.0 / dynamics.effective_mass_kg(
            dynamics.mass_kg(train.empty_mass_kg, train.full_load_mass_kg, load), train.rotating_mass_factor)
        self.ag = dynamics.track_accel_ms2(track.gradient, track.curve_specific, train.rotating_mass_factor)
        self.amax = train.max_accel_ms2
        self.ram = train.davis_a_N * self.inv_me
        self.rbm = train.davis_b_N_per_ms * self.inv_me
        self.rcm = train.davis_c_N_per_ms2 * self.inv_me
        self.tfi = tf * self.inv_me
        self.tsp, self.tef = train.traction_speed_ms, train.traction_effort_N
        # the acceleration cap can only bind below the coasting acceleration where the fall
        # alone is steeper than a_max (R ≥ 0, so a_coast ≤ a_track): test once per node
        self.steep = (self.ag >= self.amax).tolist()
        self.sawtooth = train.cruise == "sawtooth"
        self.band = train.coast_band_ms
        self.stop2 = speed_profile.stop_curve_sq(s, track.length_m, train.stop_brake_ms2)
        self.s_list, self.stop2_list = s.tolist(), self.stop2.tolist()
        self.vint_list = track.vmax_interval_ms.tolist()
        # the batch's state
        self.t, self.v, self.phase, self.ratio = state.t_s, state.v_ms, state.phase, state.ratio.copy()
        self.w = self.v * self.v
        self.cap2 = np.full(n, np.inf)  # cruise cap² per run (Command.cap_ms): none until a controller sets one
        self.shed = np.full(n, float(train.service_brake_ms2))  # deceleration onto a lowered target
        # a sawtooth vehicle that arrived anywhere but in full notch is in its coasting band
        self.coasting = (self.phase != PHASE_POWER) & self.sawtooth
        self.work = np.zeros(n)  # traction work / M_e [J/kg]
        self.maybe_over = True  # above the ceiling only after a lowered target (or a start state)
        self.lb_for = None
        self.ceil = _Ceilings(track, train)
        self.ceil.set(self.ratio, self.cap2)
        self.c0 = self.ceil.at(k0)
        self.w_last = self.w
        self.record = record
        if record:
            mr = self.m - k0
            self.rec_t, self.rec_v = np.empty((n, mr)), np.empty((n, mr))
            self.rec_a, self.rec_p = np.zeros((n, mr)), np.empty((n, mr), dtype=np.int8)
            self.rec_r, self.rec_c = np.empty((n, mr)), np.empty((n, mr))
            self.rec_t[:, 0], self.rec_v[:, 0], self.rec_p[:, 0] = self.t, self.v, self.phase
            self.rec_r[:, 0], self.rec_c[:, 0] = self.ratio, np.sqrt(self.cap2)

    # -- events -------------------------------------------------------------------
    def schedule(self, changes, controller, decision_m, snapshots_m) -> None:
        """Events at nodes: snapshots first (state before any change), then changes, then the controller."""
        track, n = self.track, self.n
        events: dict[int, list] = {}
        for sm in snapshots_m:
            events.setdefault(track.node_index(sm), []).append(("snap", sm))
        for sm, r in changes:
            events.setdefault(track.node_index(sm), []).append(("change", _as_batch(r, n, "change ratio")))
        if controller is not None:
            for sm in decision_m:
                events.setdefault(track.node_index(sm), []).append(("decide", sm))
        for k in events:
            events[k].sort(key=lambda e: ("snap", "change", "decide").index(e[0]))
        self.events, self.controller = events, controller
        self.snapshots: dict[float, RunState] = {}
        need = np.full(self.m, self.record)
        need[list(events)] = True
        need[self.m - 1] = True
        self.need_phase = need.tolist()

    def state(self, k: int) -> RunState:
        n = self.n
        return RunState(np.full(n, self.s[k]), self.t.copy(), self.v.copy(), self.phase.copy(), self.ratio.copy())

    def _events(self, k: int) -> None:
        changed = False
        s, n = self.s, self.n
        for kind, arg in self.events[k]:
            if kind == "snap":
                self.snapshots[arg] = self.state(k)
                continue
            if kind == "change":
                new = arg
                what = f"ratio change at {s[k]} m"
            else:
                cmd = self.controller(float(s[k]), self.state(k))
                if cmd is None:  # nothing to change here
                    continue
                if isinstance(cmd, Command):
                    if cmd.cap_ms is not None:
                        cap_ms = _as_batch(cmd.cap_ms, n, "controller cap_ms")
                        if np.any(~(cap_ms > 0)):
                            raise InputError(f"controller cap at {s[k]} m must be > 0 m/s")
                        self.cap2 = cap_ms * cap_ms
                    if cmd.shed_ms2 is not None:
                        shed = _as_batch(cmd.shed_ms2, n, "controller shed_ms2")
                        if np.any(~(shed > 0)):
                            raise InputError(f"controller deceleration at {s[k]} m must be > 0 m/s²")
                        self.shed = shed
                    cmd = cmd.ratio
                new = _as_batch(cmd, n, "controller ratio")
                what = f"controller ratio at {s[k]} m"
            _check_ratio(new, what)
            self.ratio = new.copy()
            changed = True
        if changed:
            self.lb_for = None
            self.ceil.set(self.ratio, self.cap2)
            self.c0 = self.ceil.at(k)
            self.maybe_over = True

    # -- free running ----------------------------------------------------------------
    def accel(self, vv, k: int):
        """Free acceleration [m/s²] at speed vv, node k (full notch, capped; or coasting) and
        the coasting acceleration ``a_track − R/M_e``."""
        coast = self.ag[k] - (self.ram + vv * (self.rbm + self.rcm * vv))
        amax = self.amax
        a = np.minimum(coast + _interp(vv, self.tsp, self.tef) * self.tfi,
                       np.maximum(amax, coast) if self.steep[k] else amax)
        if self.sawtooth:
            a = np.where(self.coasting, coast, a)
        return a, coast

    def _free(self, k: int, ds: float):
        """Heun's step in w = v²: the acceleration at both ends of the step (predictor ṽ₁)."""
        a0, cs0 = self.accel(self.v, k)
        vp = np.sqrt(np.maximum(self.w + (2.0 * ds) * a0, 0.0))
        a1, cs1 = self.accel(vp, k + 1)
        return a0, cs0, a1, cs1

    # -- the ceiling and the service brake -------------------------------------------
    def _guided(self, a0, a1, c1, st1, ds: float):
        """Free running capped by the ceiling; above it (a lowered target) braking at the shedding
        rate until it meets it. Returns the step's slope dw/ds before the crossing, its end without
        the ceiling, where it crosses, the end value and which runs were above the ceiling."""
        w, c0 = self.w, self.c0
        over = None
        if self.maybe_over:
            over = w > c0 * (1.0 + 1e-12) + 1e-9
            if not np.count_nonzero(over):
                over, self.maybe_over = None, False
        if over is None:
            slope = a0 + a1
            wend = w + slope * ds
            cross = wend > c1
            w1 = np.minimum(wend, c1)
        else:
            slope = np.where(over, -2.0 * self.shed, a0 + a1)
            wend = w + slope * ds
            cross = np.where(over, wend < c1, wend > c1)
            # braked down onto a ceiling that rises inside the step (a restriction's tail
            # clears): from the crossing the train runs free, capped by the ceiling; it must
            # not ride up the ceiling faster than it can accelerate
            fc = np.clip((w - c0) / np.where(cross, w - c0 - (wend - c1), 1.0), 0.0, 1.0)
            free = w + slope * fc * ds + (a0 + a1) * (1.0 - fc) * ds
            w1 = np.minimum(np.where(cross, np.where(over, np.minimum(c1, free), c1), wend), st1)
            self.maybe_over = bool(np.count_nonzero(over & ~cross))
        # a stalled run (w ≤ 0 before the marker) turns its time into NaN; checked in run()
        return slope, wend, cross, w1, over

    def _split(self, slope, wend, cross, w1, over, c1, cs0, cs1, ds: float):
        """Split at the crossing (root of the gap w − c², linear in s on both pieces): time
        Δt = 2Δs/(v₀ + v₁) and traction work per M_e of each piece."""
        w, v, gap0 = self.w, self.v, self.w - self.c0
        if over is None:  # gap0 ≤ 0 < gap1 on crossing lanes: the root lies in [0, ds)
            frac = np.where(cross, gap0 / (gap0 - (wend - c1)), 1.0)
        else:
            frac = np.where(cross, np.minimum(np.maximum(gap0 / (gap0 - (wend - c1)), 0.0), 1.0), 1.0)
        xc = frac * ds
        wc = w + slope * xc
        vc = np.sqrt(wc)
        v1 = np.sqrt(w1)
        rest = ds - xc
        dt = 2.0 * (xc / (v + vc) + rest / (vc + v1))
        # traction work / M_e on each piece: F·Δs = M_e (Δw/2 − a_coast Δs), when positive
        # (the free piece is (a − a_coast) Δs ≥ 0 under power, 0 when coasting)
        cb = 0.5 * (cs0 + cs1)
        if over is None:
            dwork = xc * (0.5 * slope - cb) + np.maximum(0.5 * (w1 - wc) - rest * cb, 0.0)
        else:
            dwork = (np.maximum(0.5 * (wc - w) - xc * cb, 0.0)
                     + np.maximum(0.5 * (w1 - wc) - rest * cb, 0.0))
        return wc, vc, w1, v1, xc, rest, dt, dwork, cb

    # -- the sawtooth band ---------------------------------------------------------
    def _band_edge(self, k: int) -> None:
        """The band's lower edge ``max(target − band, 0.5 target)``, squared; it changes with the target only."""
        if self.vint_list[k] != self.lb_for:
            self.lb_for = self.vint_list[k]
            tgt = np.minimum(self.ratio * self.lb_for, np.sqrt(self.cap2))
            self.lb = np.maximum(tgt - self.band, SAWTOOTH_MIN_FRACTION * tgt)
            self.lb2 = self.lb * self.lb

    def _sawtooth(self, k: int, ds: float, cross, c1, wend, wc, vc, w1, v1, xc, rest, dt, dwork, cb, cs1):
        """A sawtooth vehicle coasts from where it meets a level or falling ceiling (still capped
        by it), and powers again from the band's lower edge, splitting the step there."""
        w, v = self.w, self.v
        hit = cross & (c1 <= self.c0 * (1 + 1e-12))
        if np.count_nonzero(hit):
            wco = np.minimum(wc + 2.0 * cs1 * rest, c1)
            wco = np.where(hit, wco, w1)
            vco = np.sqrt(wco)
            dt = 2.0 * (xc / (v + vc) + rest / (vc + vco))
            dwork = np.where(hit, np.maximum(0.5 * (wc - w) - xc * cb, 0.0)
                             + np.maximum(0.5 * (wco - wc) - rest * cb, 0.0), dwork)
            w1, v1 = wco, vco
        # coasting below the band's lower edge: split there and power the rest of the step
        band_i = None
        lb2 = self.lb2
        band_x = self.coasting & ~cross & (wend < lb2)
        if np.count_nonzero(band_x):
            band_i = i = np.flatnonzero(band_x)
            xb = ds * np.clip((w[i] - lb2[i]) / (w[i] - wend[i]), 0.0, 1.0)
            self.coasting[i] = False
            sub = ds - xb
            vb, tfb = self.lb[i], self.tfi[i]
            ram, rbm, rcm, ag, amax = self.ram, self.rbm, self.rcm, self.ag, self.amax
            cb_i = ag[k + 1] - (ram[i] + vb * (rbm[i] + rcm[i] * vb))
            aa = np.minimum(cb_i + np.interp(vb, self.tsp, self.tef) * tfb, np.maximum(amax, cb_i))
            vq = np.sqrt(np.maximum(lb2[i] + 2.0 * aa * sub, 0.0))
            cq = ag[k + 1] - (ram[i] + vq * (rbm[i] + rcm[i] * vq))
            ab = np.minimum(cq + np.interp(vq, self.tsp, self.tef) * tfb, np.maximum(amax, cq))
            wq = np.minimum(lb2[i] + (aa + ab) * sub, c1[i])
            vq = np.sqrt(wq)
            w1[i], v1[i] = wq, vq
            dt[i] = 2.0 * (xb / (v[i] + vb) + sub / (vb + vq))
            dwork[i] = np.maximum(0.5 * (wq - lb2[i]) - sub * 0.5 * (cb_i + cq), 0.0)
        # at the ceiling a sawtooth vehicle coasts (not where the ceiling ramps up: it powers)
        self.coasting |= cross & (c1 <= self.c0 * (1 + 1e-12))
        return w1, v1, dt, dwork, band_i

    # -- phase codes and recording -------------------------------------------------------
    def _phase(self, over, cross, c1, w1, st1, coasting_step, band_i) -> None:
        n, c0 = self.n, self.c0
        if self.sawtooth:
            ph = np.where(coasting_step, PHASE_COAST, PHASE_POWER)
        else:
            ph = np.full(n, PHASE_POWER)
        if over is not None:
            ph = np.where(over, PHASE_BRAKE, ph)
        cph = np.where(c1 < c0 * (1 - 1e-12), PHASE_BRAKE,
                       np.where(c1 > c0 * (1 + 1e-12), PHASE_POWER, PHASE_HOLD))
        ph = np.where(cross, cph, ph).astype(np.int8)
        if self.sawtooth:
            ph[cross & (w1 < c1 * (1 - 1e-12))] = PHASE_COAST
        if band_i is not None:
            ph[band_i] = PHASE_POWER
        ph[w1 >= st1] = PHASE_STOP
        self.phase = ph

    def _record(self, k: int, w1, v1, dt, ds: float) -> None:
        jr = k + 1 - self.k0
        self.rec_t[:, jr], self.rec_v[:, jr], self.rec_p[:, jr] = self.t + dt, v1, self.phase
        self.rec_r[:, jr], self.rec_c[:, jr] = self.ratio, np.sqrt(self.cap2)
        self.rec_a[:, jr] = (w1 - self.w) / (2.0 * ds)

    # -- the loop -------------------------------------------------------------------------
    def run(self) -> None:
        s_list, m = self.s_list, self.m
        k_last_ok = self.k0
        for k in range(self.k0, m - 1):
            if k in self.events:
                self._events(k)
            ds = s_list[k + 1] - s_list[k]
            c1 = self.ceil.at(k + 1)
            st1 = self.stop2_list[k + 1]
            if self.sawtooth:
                self._band_edge(k)
                self.coasting &= self.w > self.lb2
                coasting_step = self.coasting.copy()
            a0, cs0, a1, cs1 = self._free(k, ds)
            slope, wend, cross, w1, over = self._guided(a0, a1, c1, st1, ds)
            wc, vc, w1, v1, xc, rest, dt, dwork, cb = self._split(slope, wend, cross, w1, over, c1, cs0, cs1, ds)
            band_i = None
            if self.sawtooth:
                w1, v1, dt, dwork, band_i = self._sawtooth(k, ds, cross, c1, wend, wc, vc, w1, v1, xc, rest, dt,
                                                           dwork, cb, cs1)
            if self.need_phase[k + 1]:
                self._phase(over, cross, c1, w1, st1, coasting_step if self.sawtooth else None, band_i)
            if self.record:
                self._record(k, w1, v1, dt, ds)
            if k + 2 == m:
                self.w_last = self.w  # entering the last step, onto the marker
            self.w, self.v = w1, v1
            self.t = self.t + dt
            self.work += dwork
            self.c0 = c1
            if (k & 63) == 0 or k + 2 >= m - 1:
                _check_stall(self.t, self.track, self.train, self.load, self.tf, s_list, k_last_ok, k + 1)
                k_last_ok = k + 1

    def result(self) -> BatchResult:
        s, m, train = self.s, self.m, self.train
        energy = self.work * (1.0 / self.inv_me)
        for kind, arg in self.events.get(m - 1, []):
            if kind == "snap":
                self.snapshots[arg] = self.state(m - 1)
        # the last step ends standing on the marker; had it asked more than the stopping
        # brake gives (w above 2 β Δs entering it), the train would have run past by this much
        overrun = (np.maximum(self.w_last / (2.0 * train.stop_brake_ms2) - (s[-1] - s[-2]), 0.0)
                   if m - 1 > self.k0 else np.zeros(self.n))
        stop_m = self.track.length_m + overrun
        energy_kwh = energy / KWH
        if not self.record:
            return BatchResult(time_s=self.t, energy_kwh=energy_kwh, snapshots=self.snapshots, stop_m=stop_m)
        rec_a = self.rec_a
        if rec_a.shape[1] > 1:
            rec_a[:, 0] = rec_a[:, 1]
        return BatchResult(time_s=self.t, energy_kwh=energy_kwh, snapshots=self.snapshots, stop_m=stop_m,
                           s_m=s[self.k0:].copy(), t_s=self.rec_t, v_ms=self.rec_v, a_ms2=rec_a,
                           phase=self.rec_p, ratio=self.rec_r, cap_ms=self.rec_c)
