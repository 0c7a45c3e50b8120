"""Run curves: the distance-domain, lock-step batch integrator (docs/design.md §2, §3).

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

The loop is :class:`_Integrator`: it handles the nodes where something can
change (snapshots, ratio changes, the controller hook, the ceiling's segment
table) and hands every grid step between two such nodes to the compiled
kernel :func:`planner.physics.kernel.advance` (free running, ceiling and
brake, sawtooth band, phase codes, recording); runs of the batch that meet in
the same state are stepped once from there, with the same results to the bit
(:mod:`planner.physics.reuse`). It is the one integrator: the
tables, the closed loop of every on-board mode (the ratio modes and the
time-keeping mode, through :class:`Command`), the margins and the run-curve
API all run through it.

Energy is the mechanical traction work at the wheel ``∫ F ds`` while F > 0
(regenerative braking not credited), in kWh.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Callable, NamedTuple, Sequence

import numpy as np

from planner.errors import InputError, StallError
from planner.line.model import TrainType
from planner.line.units import KWH
from planner.physics import dynamics, kernel_abi as K, reuse, speed_profile
from planner.physics.kernel_abi import (  # noqa: F401  (the phase codes and the band's floor are part of this API)
    PHASE_BRAKE, PHASE_COAST, PHASE_HOLD, PHASE_POWER, PHASE_STOP, SAWTOOTH_MIN_FRACTION,
)
from planner.physics.track import NODE_TOL_M, Track

PHASE_NAMES = ("power", "hold", "coast", "brake", "stop")
_KERNEL = K.load()
"""The kernel's entry points: its build from install, else numba's just-in-time compile (kernel_abi)."""


@dataclass(frozen=True)
class RunState:
    """State of n runs at one grid node; every array has shape (n,).

    Attributes
    ----------
    s_m : running distance [m]; t_s : time since departure [s]; v_ms : speed [m/s];
    phase : int8 phase code of the step that arrived here (``PHASE_*``);
    ratio : target-speed ratio in force on that step;
    w_ms2 : the integrator's own speed² [m²/s²] and coasting : a sawtooth vehicle in its
    coasting band (bool), both set in the snapshots of :func:`simulate`. A run started from
    a snapshot then goes on exactly, to the bit, as the run it was taken from would; left
    None (a state made by hand), they follow from ``v_ms`` and ``phase``.
    """

    s_m: np.ndarray
    t_s: np.ndarray
    v_ms: np.ndarray
    phase: np.ndarray
    ratio: np.ndarray
    w_ms2: np.ndarray | None = None
    coasting: np.ndarray | None = None


class Command(NamedTuple):
    """What an on-board controller asks of the runs at a decision node (each array shape (n,)).

    A controller (see :func:`simulate`) returns either a plain ratio array or a
    Command. The target is ``min(ratio × on-board maximum, cap_ms)``: the ratio
    modes of docs/design.md §3 leave ``cap_ms`` at +inf; the time-keeping mode of §4
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


class _Prep:
    """What the kernel reads per node of one track, for one train's brakes, inertia and a_max.

    The ceiling without an (n, m) table: between two changes of the on-board maximum
    the target is constant, so the backward recursion only matters at those change
    nodes ``K_e``: with ``E_e`` = service-brake ceiling at the end node of segment e,
    ``c²_k = min(r² V_k², E_e + 2 b (s_end(e) − s_k), 2 b_stop (L − s_k))`` for k in
    segment e. ``E`` (segments, n) is :func:`planner.physics.kernel.set_targets`'s, whenever
    the ratios change; the segment of each node and ``2 b (s_end(e) − s_k)`` are here.
    Built once per track and train constants (:meth:`of`): a track is run many times.
    """

    def __init__(self, track: Track, train: TrainType):
        s, vi = track.s_m, track.vmax_interval_ms
        m = len(s)
        bounds = np.concatenate([[0], np.flatnonzero(np.diff(vi) != 0.0) + 1, [m - 1]])
        seg = np.searchsorted(bounds, np.arange(m), side="right") - 1  # segment starting at/containing k
        seg[-1] = len(bounds) - 1  # the arrival node: nothing ahead (column of +inf)
        send = s[bounds[np.minimum(seg + 1, len(bounds) - 1)]]
        ag = dynamics.track_accel_ms2(track.gradient, track.curve_specific, train.rotating_mass_factor)
        trk = np.empty((7, m))
        trk[K.T_S] = s
        trk[K.T_VN2] = track.vmax_ms ** 2
        trk[K.T_AHEAD] = 2.0 * train.service_brake_ms2 * (send - s)
        trk[K.T_STOP2] = speed_profile.stop_curve_sq(s, track.length_m, train.stop_brake_ms2)
        trk[K.T_AG] = ag
        trk[K.T_VINT, :-1] = vi
        trk[K.T_VINT, -1] = vi[-1]
        # the acceleration cap can only bind below the coasting acceleration where the fall
        # alone is steeper than a_max (R ≥ 0, so a_coast ≤ a_track)
        trk[K.T_STEEP] = ag >= train.max_accel_ms2
        self.trk, self.seg, self.bounds = trk, seg.astype(np.int64), bounds.astype(np.int64)
        K.check_layout(trk=self.trk, seg=self.seg, bounds=self.bounds)

    @staticmethod
    def of(track: Track, train: TrainType) -> "_Prep":
        key = (train.service_brake_ms2, train.stop_brake_ms2, train.rotating_mass_factor, train.max_accel_ms2)
        per_track = _PREPARED.get(track)
        if per_track is None:
            per_track = _PREPARED[track] = {}
        prep = per_track.get(key)
        if prep is None:
            prep = per_track[key] = _Prep(track, train)
        return prep


_PREPARED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Per track (while it lives), its :class:`_Prep` per train constants; kept out of the track, so never pickled with it."""


def _effort_table(train: TrainType) -> np.ndarray:
    """The tractive-effort table for the kernel's ``np.interp`` (rows: speed, effort, slope of each piece),
    made once per train type object (while it lives) and its curve's arrays, not at every batch."""
    speed, effort = train.traction_speed_ms, train.traction_effort_N
    hit = _EFFORT.get(train)
    if hit is not None and hit[0] is speed and hit[1] is effort:
        return hit[2]
    tab = np.zeros((3, len(speed)))
    tab[0], tab[1] = speed, effort
    tab[2, :-1] = np.diff(tab[1]) / np.diff(tab[0])
    K.check_layout(tab=tab)
    _EFFORT[train] = (speed, effort, tab)
    return tab


_EFFORT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Per train type object (compared by identity), its curve's arrays and :func:`_effort_table`."""


def _stall_error(track, train, load, tf, s, j: int, k_ok: int, k: int) -> StallError:
    """Run j stalled (v = sqrt(w ≤ 0): its time turned NaN or infinite) between nodes k_ok and k."""
    a, b = sorted((float(track.position_m(s[k_ok])), float(track.position_m(s[k]))))
    return StallError(
        f"train type {train.train_type} stalls on {track.origin}->{track.destination} between chainage "
        f"{a:.0f} and {b:.0f} m (run {j}: load {load[j]:g}, traction factor {tf[j]:g}): tractive effort "
        "cannot overcome resistance and gradient; check its effort (traction.parquet), its mass and Davis terms "
        "(rolling_stock.parquet) and the gradients",
        (a, b), float(load[j]), float(tf[j]))


def _as_batch(x, n: int, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise InputError(f"{name} must be a scalar or an array of shape ({n},), got shape {a.shape}")
    return a.copy()


def _check_ratio(r: np.ndarray, what: str) -> None:
    if not ((r > 0) & (r <= 1.0 + 1e-12)).all():
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
    StallError
        If a run stalls (tractive effort cannot overcome resistance and gradient): an
        :class:`~planner.errors.InfeasibleError` that says where (chainage) and under which load
        and traction.
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
    if (load < 0).any() or (tf <= 0).any():
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
                         phase, ratio,
                         None if start.w_ms2 is None else _as_batch(start.w_ms2, n, "start.w_ms2"),
                         None if start.coasting is None else np.asarray(start.coasting, bool).reshape(-1))
    run = _Integrator(track, train, load, tf, state, k0, record)
    run.schedule(changes, controller, decision_m, snapshots_m)
    with np.errstate(divide="ignore", invalid="ignore"):
        run.run()
    return run.result()


class _Integrator:
    """One batch of runs through :func:`simulate` (module doc for the method).

    The loop (:meth:`run`) goes from event node to event node: the events at a
    node (:meth:`_events`: snapshots, ratio changes, the controller), then every
    grid step up to the next event node in the compiled kernel
    (:func:`planner.physics.kernel.advance`: free running, ceiling and service
    brake, sawtooth band, phase codes, recording). The batch lives in a few
    arrays the kernel updates in place (row constants in :mod:`~planner.physics.kernel_abi`):
    ``par`` per-run constants, ``st`` the state, ``lane`` phase and coasting flag,
    ``e`` the ceiling's segment table, ``flags`` the batch-wide switches.
    """

    kernel = _KERNEL

    def __init__(self, track: Track, train: TrainType, load: np.ndarray, tf: np.ndarray, state: RunState,
                 k0: int, record: bool):
        self.track, self.train, self.load, self.tf = track, train, load, tf
        self.s, self.m, self.k0, self.n = track.s_m, len(track.s_m), k0, load.size
        n = self.n
        self.prep = _Prep.of(track, train)
        # the plant: per-run constants divided by M_e (the loop works in accelerations, and the
        # traction work per unit M_e follows from the energy balance of each piece)
        self.inv_me = inv_me = 1.0 / dynamics.effective_mass_kg(
            dynamics.mass_kg(train.empty_mass_kg, train.full_load_mass_kg, load), train.rotating_mass_factor)
        sawtooth = train.cruise == "sawtooth"
        par = self.par = np.empty((9, n))
        par[K.P_RAM] = train.davis_a_N * inv_me
        par[K.P_RBM] = train.davis_b_N_per_ms * inv_me
        par[K.P_RCM] = train.davis_c_N_per_ms2 * inv_me
        par[K.P_TFI] = tf * inv_me
        par[K.P_RATIO] = state.ratio
        par[K.P_CAP2] = par[K.P_CAPV] = np.inf  # cruise cap (Command.cap_ms): none until a controller sets one
        par[K.P_SHED] = float(train.service_brake_ms2)  # deceleration onto a lowered target
        st = self.st = np.empty((K.S_ROWS, n))
        st[K.S_T], st[K.S_V] = state.t_s, state.v_ms
        st[K.S_W] = st[K.S_V] * st[K.S_V] if state.w_ms2 is None else state.w_ms2
        st[K.S_WORK] = 0.0  # traction work / M_e [J/kg]
        st[K.S_BAD] = np.inf
        lane = self.lane = np.empty((2, n), dtype=np.int8)
        lane[K.L_PHASE] = state.phase
        # a sawtooth vehicle that arrived anywhere but in full notch is in its coasting band
        lane[K.L_COAST] = ((state.phase != PHASE_POWER) if state.coasting is None else state.coasting) & sawtooth
        self.cst = np.array([train.max_accel_ms2, train.coast_band_ms, float(sawtooth)])
        self.tab = _effort_table(train)
        # above the ceiling only after a lowered target (or a start state); the stall check's last node
        self.flags = np.array([1, k0, -1, -1, -1], dtype=np.int64)
        self.e = np.empty((len(self.prep.bounds), n))  # the ceiling's segment table (kernel.set_targets)
        self.record = record
        self.rec, self.rec_p = ((np.zeros((5, n, self.m - k0)), np.empty((n, self.m - k0), np.int8)) if record
                                else (K.NO_REC, K.NO_REC_P))
        K.check_layout(par=par, st=st, lane=lane, e=self.e, cst=self.cst, flags=self.flags, rec=self.rec,
                       rec_p=self.rec_p)  # the track's and the train's tables are checked where they are cached
        _KERNEL.set_targets(k0, self.prep.trk, self.prep.seg, self.prep.bounds, par, st, self.e)
        st[K.S_WLAST] = st[K.S_W]
        if record:
            self.rec[K.R_T, :, 0], self.rec[K.R_V, :, 0] = st[K.S_T], st[K.S_V]
            self.rec[K.R_RATIO, :, 0], self.rec[K.R_CAP, :, 0] = par[K.P_RATIO], par[K.P_CAPV]
            self.rec_p[:, 0] = lane[K.L_PHASE]

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

    def state(self, k: int) -> RunState:
        st = self.st
        return RunState(np.full(self.n, self.s[k]), st[K.S_T].copy(), st[K.S_V].copy(),
                        self.lane[K.L_PHASE].copy(), self.par[K.P_RATIO].copy(), st[K.S_W].copy(),
                        self.lane[K.L_COAST] != 0)

    def _events(self, k: int) -> None:
        changed = False
        s, n, par = self.s, self.n, self.par
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
                        was_cap = par[K.P_CAPV].copy()
                        cap_ms = _as_batch(cmd.cap_ms, n, "controller cap_ms")
                        if np.any(~(cap_ms > 0)):
                            raise InputError(f"controller cap at {s[k]} m must be > 0 m/s")
                        par[K.P_CAP2] = cap_ms * cap_ms
                        par[K.P_CAPV] = np.sqrt(par[K.P_CAP2])
                        # the cap lifted (the time-keeping mode's "late: flat out"): a sawtooth run
                        # in its coasting band powers from here, as a driver does, instead of coasting
                        # on to the band's lower edge, which a falling grade may never let it reach. A
                        # cap raised to a finite speed keeps the band (the cap aims the band's middle),
                        # and so does a raised ratio (tables (b)-(d) step ratio changes with the band kept).
                        self.lane[K.L_COAST, np.isinf(par[K.P_CAPV]) & (par[K.P_CAPV] > was_cap)] = 0
                    if cmd.shed_ms2 is not None:
                        shed = _as_batch(cmd.shed_ms2, n, "controller shed_ms2")
                        if np.any(~(shed > 0)):
                            raise InputError(f"controller deceleration at {s[k]} m must be > 0 m/s²")
                        par[K.P_SHED] = shed
                    cmd = cmd.ratio
                new = _as_batch(cmd, n, "controller ratio")
                what = f"controller ratio at {s[k]} m"
            _check_ratio(new, what)
            par[K.P_RATIO] = new
            changed = True
        if changed:
            _KERNEL.set_targets(k, self.prep.trk, self.prep.seg, self.prep.bounds, par, self.st, self.e)
            self.flags[K.F_MAYBE_OVER] = 1

    # -- the loop -------------------------------------------------------------------------
    def run(self) -> None:
        m, k = self.m, self.k0
        # runs that meet in the same state are stepped once from there (planner.physics.reuse); not
        # while recording every run's curve
        same = reuse.Reuse(self) if reuse.ENABLED and not self.record and self.n >= reuse.MIN_RUNS else None
        for k_next in sorted(j for j in self.events if k < j < m - 1) + [m - 1]:
            if k in self.events:
                self._events(k)
            if same is not None:
                same.advance(k, k_next)
            else:
                _KERNEL.advance(k, k_next, self.k0, self.prep.trk, self.prep.seg, self.par, self.st, self.lane,
                                self.e, self.cst, self.tab, self.flags, self.rec, self.rec_p, self.record, K.NO_INC,
                                K.NO_SLOT)
            if self.flags[K.F_STALL_TO] >= 0:
                f = self.flags
                raise _stall_error(self.track, self.train, self.load, self.tf, self.s, int(f[K.F_STALL_RUN]),
                                   int(f[K.F_STALL_FROM]), int(f[K.F_STALL_TO]))
            k = k_next

    def result(self) -> BatchResult:
        s, m, train, st = self.s, self.m, self.train, self.st
        energy = st[K.S_WORK] * (1.0 / self.inv_me)
        for kind, arg in self.events.get(m - 1, []):
            if kind == "snap":
                self.snapshots[arg] = self.state(m - 1)
        # the last step ends standing on the marker; had it asked more than the stopping
        # brake gives (w above 2 β Δs entering it), the train would have run past by this much
        overrun = (np.maximum(st[K.S_WLAST] / (2.0 * train.stop_brake_ms2) - (s[-1] - s[-2]), 0.0)
                   if m - 1 > self.k0 else np.zeros(self.n))
        stop_m = self.track.length_m + overrun
        energy_kwh = energy / KWH
        t = st[K.S_T].copy()
        if not self.record:
            return BatchResult(time_s=t, energy_kwh=energy_kwh, snapshots=self.snapshots, stop_m=stop_m)
        rec = self.rec
        if rec.shape[2] > 1:
            rec[K.R_A, :, 0] = rec[K.R_A, :, 1]
        return BatchResult(time_s=t, energy_kwh=energy_kwh, snapshots=self.snapshots, stop_m=stop_m,
                           s_m=s[self.k0:].copy(), t_s=rec[K.R_T], v_ms=rec[K.R_V], a_ms2=rec[K.R_A],
                           phase=self.rec_p, ratio=rec[K.R_RATIO], cap_ms=rec[K.R_CAP])
