"""Domain model of a line, in SI units.

These frozen dataclasses are what the loader returns and what every later step
consumes; no DataFrame travels past the loader. Every quantity is SI (m, s,
m/s, m/s², m/s³, N, kg) and its unit is written in the field name's suffix:

``_m`` metres, ``_s`` seconds, ``_ms`` metres per second, ``_ms2`` m/s²,
``_ms3`` m/s³, ``_kg`` kilograms, ``_N`` newtons. Gradients are stored as the
dimensionless rise per metre (‰ / 1000), positive when rising towards
increasing chainage.

Direction ``"down"`` runs towards increasing chainage, ``"up"`` towards
decreasing chainage. ``sign(direction)`` is +1 for down, -1 for up.
"""
from __future__ import annotations

import functools
import weakref
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from planner.errors import UnknownNameError

Direction = Literal["down", "up"]
DIRECTIONS: tuple[Direction, Direction] = ("down", "up")
G = 9.80665
"""Standard gravity [m/s²]."""


def sign(direction: str) -> int:
    """+1 for ``down`` (increasing chainage), -1 for ``up``."""
    if direction == "down":
        return 1
    if direction == "up":
        return -1
    raise ValueError(f"direction must be 'down' or 'up', not {direction!r}")


@dataclass(frozen=True, eq=False)
class Segments:
    """A piecewise-constant quantity over chainage; gaps mean "none" (level, straight).

    Attributes
    ----------
    start_m, end_m : ndarray
        Segment bounds [m], sorted, non-overlapping, start < end.
    value : ndarray
        The quantity on each segment (gradient as rise/m, or curve radius [m]).
    """

    start_m: np.ndarray
    end_m: np.ndarray
    value: np.ndarray

    @staticmethod
    def empty() -> "Segments":
        z = np.zeros(0)
        return Segments(z, z.copy(), z.copy())

    def __len__(self) -> int:
        return len(self.start_m)


@dataclass(frozen=True)
class Station:
    """A station. Positions are chainages [m]."""

    station_id: str
    name: str
    position_m: float
    stop_down_m: float
    stop_up_m: float
    platform_length_m: float

    def stop_m(self, direction: str) -> float:
        """Stop marker for the train front in ``direction`` [m]."""
        return self.stop_down_m if direction == "down" else self.stop_up_m


@dataclass(frozen=True)
class SpeedLimit:
    """A speed restriction on the stretch [start_m, end_m] (front of train).

    ``train_type`` None applies to every train type; ``direction`` is
    ``both``, ``down`` or ``up``. ``row`` is the 0-based row in
    speed_limits.parquet, used as a stable id (``R<row>``). A temporary
    restriction of the daily feed in force that day (kind ``temporary``) has
    ``row`` -1 and its feed id in ``restriction_id``, so its place in the feed
    file keys nothing.
    """

    start_m: float
    end_m: float
    limit_ms: float
    direction: str
    train_type: str | None
    kind: str
    has_beacon: bool
    row: int = -1
    restriction_id: str = ""

    def applies(self, direction: str, train_type: str) -> bool:
        return self.direction in ("both", direction) and self.train_type in (None, train_type)

    @property
    def ident(self) -> str:
        """The id that names it in bundles: ``R<row>`` for a restriction of the line, ``T.<restriction_id>``
        for a temporary one (the prefix keeps a feed id such as ``R1`` apart from the line's row 1)."""
        return f"T.{self.restriction_id}" if self.restriction_id else f"R{self.row}"


@dataclass(frozen=True)
class Beacon:
    """A ground beacon (transponder) read by trains running in ``direction``."""

    beacon_id: str
    position_m: float
    direction: str
    kind: str  # signal, pattern_update, tasc, other
    telegram: str
    evaluation_point: bool


@dataclass(frozen=True)
class Signal:
    """A block signal (block boundary) for trains running in ``direction``."""

    signal_id: str
    position_m: float
    direction: str


@dataclass(frozen=True, eq=False)
class TrainType:
    """Rolling stock of one train type, in SI.

    Davis resistance R(v) = davis_a_N + davis_b_N_per_ms·v + davis_c_N_per_ms2·v²
    [N] with v in m/s. ``traction_speed_ms``/``traction_effort_N`` is the
    full-notch tractive-effort curve of the whole train (linear interpolation).
    """

    train_type: str
    length_m: float
    empty_mass_kg: float
    full_load_mass_kg: float
    rotating_mass_factor: float
    max_speed_ms: float
    max_accel_ms2: float
    davis_a_N: float
    davis_b_N_per_ms: float
    davis_c_N_per_ms2: float
    service_brake_ms2: float
    stop_brake_ms2: float
    atsp_pattern_ms2: float
    brake_comfort_ms2: float
    jerk_limit_ms3: float
    speed_margin_ms: float
    cruise: str  # "constant" or "sawtooth"
    coast_band_ms: float
    traction_speed_ms: np.ndarray
    traction_effort_N: np.ndarray

    def mass_kg(self, load: float = 0.0) -> float:
        """Static mass M = empty + load × full passenger mass [kg]."""
        return self.empty_mass_kg + load * self.full_load_mass_kg

    def effective_mass_kg(self, load: float = 0.0) -> float:
        """Effective (inertial) mass M_e = M (1 + rotating-mass factor) [kg]."""
        return self.mass_kg(load) * (1.0 + self.rotating_mass_factor)


@dataclass(frozen=True, slots=True)
class Call:
    """One call of a timetabled train at a station (times in s after midnight, NaN if none)."""

    seq: int
    station_id: str
    arrival_s: float
    departure_s: float
    stops: bool


@dataclass(frozen=True)
class Train:
    """A timetabled train: its type, direction and calls in running order."""

    train_id: str
    train_type: str
    direction: str
    calls: tuple[Call, ...]

    def stop_indices(self) -> list[int]:
        """Indices of the calls that end or begin a leg: every stop, and the first and last call (a run
        starts and ends there even when the timetable marks them as passes)."""
        last = len(self.calls) - 1
        return [k for k, c in enumerate(self.calls) if c.stops or k in (0, last)]

    def stop_calls(self) -> list[Call]:
        """The calls of :meth:`stop_indices`: consecutive pairs are the train's legs, in running order."""
        return [self.calls[k] for k in self.stop_indices()]


@dataclass(frozen=True)
class Node:
    node_id: str
    kind: str  # switch, stop, boundary, end
    position_m: float
    interlocking: str
    station_id: str | None = None  # optional nodes.parquet column: the station a stop node serves
    track: str | None = None  # optional nodes.parquet column


@dataclass(frozen=True)
class Edge:
    edge_id: str
    from_node: str
    to_node: str
    length_m: float
    track: str
    direction: str | None = None
    """down, up or both (``edges.direction``); None: from the track's name (:func:`planner.network.routes.track_direction`)."""


@dataclass(frozen=True)
class Network:
    """Track network: nodes (switches, stop targets, boundaries) and track pieces."""

    nodes: tuple[Node, ...]
    edges: tuple[Edge, ...]


@dataclass(frozen=True)
class RunExtent:
    """Where a run between two stations lies: from the origin's stop marker to the destination's.

    ``start_m``/``end_m`` are chainages [m]; ``length_m`` the running distance
    (positive when the markers leave room to run); running distance s maps to
    chainage ``start_m + sign * s``.
    """

    direction: Direction
    sign: int
    start_m: float
    end_m: float
    length_m: float


@dataclass(frozen=True, eq=False)
class Line:
    """A validated line database, in SI.

    ``source_digest`` is the SHA-256 over the input files (names and bytes) it
    was loaded from; "" for lines built in memory. ``max_speed_ms`` is ``inf`` when the line
    sets no maximum (each train's own maximum holds where no restriction does). ``approach_m``: the line's optional
    ``approach_m`` column (None when absent or null).
    """

    line_id: str
    name: str
    start_m: float
    end_m: float
    max_speed_ms: float
    schema_version: int
    stations: tuple[Station, ...]
    gradients: Segments
    curves: Segments
    speed_limits: tuple[SpeedLimit, ...]
    beacons: tuple[Beacon, ...]
    signals: tuple[Signal, ...]
    train_types: tuple[TrainType, ...]
    trains: tuple[Train, ...]
    network: Network | None = None
    source_digest: str = ""
    source_path: str = field(default="", compare=False)
    approach_m: float | None = None
    """Stopping-pattern start before the marker where no TASC beacon is [m]; None: from the physics."""
    running_side: str | None = None
    """right or left: the side trains normally run on (``line.running_side``); None: not given."""
    upgrade_notes: tuple[str, ...] = field(default=(), compare=False)
    """What was read differently from an earlier schema version of the folder (:mod:`planner.line.upgrade`)."""

    # --- look-ups -----------------------------------------------------------
    def station(self, station_id: str) -> Station:
        """The station with this id; an exact match first, else the one match ignoring case."""
        hit = _index(self).stations.get(station_id)
        return hit if hit is not None else _lookup(self.stations, "station_id", station_id, "station", self.line_id)

    def train_type(self, train_type: str) -> TrainType:
        """The train type with this id; an exact match first, else the one match ignoring case."""
        return _lookup(self.train_types, "train_type", train_type, "train type", self.line_id)

    def direction_between(self, origin: str, destination: str) -> Direction:
        """``down`` if destination lies at greater chainage than origin, else ``up``."""
        a, b = self.station(origin), self.station(destination)
        if a.station_id == b.station_id:
            raise UnknownNameError(f"origin and destination are the same station {origin!r}")
        return "down" if b.position_m > a.position_m else "up"

    def run_between(self, origin: str, destination: str) -> RunExtent:
        """Direction, stop markers and running distance of a run ``origin`` → ``destination``."""
        d = self.direction_between(origin, destination)
        a, b = self.station(origin).stop_m(d), self.station(destination).stop_m(d)
        return RunExtent(d, sign(d), a, b, sign(d) * (b - a))

    def interstations(self, direction: str) -> list[tuple[Station, Station]]:
        """Consecutive station pairs in running order for ``direction``."""
        st = sorted(self.stations, key=lambda s: s.position_m, reverse=(direction == "up"))
        return list(zip(st[:-1], st[1:]))

    def beacons_for(self, direction: str, within: tuple[float, float] | None = None) -> list[Beacon]:
        """Beacons read in ``direction``, in running order; with ``within`` = (lo, hi) [m], only those at
        lo ≤ position_m ≤ hi (a search in the line's index, not a pass over every beacon)."""
        b, pos = _index(self).beacons_for(self, direction)
        if within is None:
            return list(b)
        lo, hi = (float(x) for x in within)
        ks = pos * sign(direction)  # ascending: running order
        a, z = sorted((lo * sign(direction), hi * sign(direction)))
        return list(b[int(np.searchsorted(ks, a, side="left")):int(np.searchsorted(ks, z, side="right"))])

    def beacons_on(self, ext: "RunExtent") -> list[Beacon]:
        """Beacons read on the run ``ext`` (:meth:`run_between`), in running order: those from a metre before its
        start to a metre past its end (the caller's test on the running distance decides at the ends)."""
        return self.beacons_for(ext.direction, within=(ext.start_m - ext.sign, ext.end_m + ext.sign))

    def limits_for(self, direction: str, train_type: str) -> list[SpeedLimit]:
        """Speed restrictions that apply to ``direction`` and ``train_type``."""
        return [s for s in self.speed_limits if s.applies(direction, train_type)]

    # --- the slice one run can see --------------------------------------------
    def window_m(self, origin: str, destination: str, train_type: str) -> tuple[float, float]:
        """Chainage range [m] a run ``origin`` → ``destination`` of ``train_type`` can see.

        The stretch between the two stop markers widened by one train length
        (and 1 m) on both sides: restrictions hold until the tail clears them and
        gradients and curves are averaged over the train, so anything within a
        train length behind the departure can matter.
        """
        ext = self.run_between(origin, destination)
        length = self.train_type(train_type).length_m
        return min(ext.start_m, ext.end_m) - length - 1.0, max(ext.start_m, ext.end_m) + length + 1.0

    def window(self, origin: str, destination: str, train_type: str) -> "Line":
        """The line as one run ``origin`` → ``destination`` of ``train_type`` sees it (:meth:`window_m`).

        The two stations, the gradient and curve segments, restrictions and
        beacons that reach into the window (whole, not clipped), this train
        type; no other station, train type, signal, timetable or network. A
        parallel unit of work gets this instead of the whole line, so what it
        ships does not grow with the line; every result of the run is the same
        as on the whole line (the job's cache key is this same slice).
        """
        lo, hi = self.window_m(origin, destination, train_type)
        tt = self.train_type(train_type)
        two = sorted((self.station(origin), self.station(destination)), key=lambda st: st.position_m)

        def seg(x: Segments) -> Segments:
            m = (x.end_m > lo) & (x.start_m < hi)
            return Segments(x.start_m[m], x.end_m[m], x.value[m])

        ix = _index(self)
        return replace(
            self, stations=tuple(two), gradients=seg(self.gradients), curves=seg(self.curves),
            speed_limits=tuple(self.speed_limits[i] for i in np.flatnonzero((ix.limit_end_m > lo)
                                                                            & (ix.limit_start_m < hi))),
            beacons=tuple(self.beacons[i] for i in np.flatnonzero((lo < ix.beacon_m) & (ix.beacon_m < hi))),
            signals=(), train_types=(tt,), trains=(), network=None,
        )


class _Index:
    """What :meth:`Line.station` and :meth:`Line.window` look things up in, made once per line (it is frozen):
    the stations by id (the first of an id, as :func:`_lookup` finds it), the restrictions' and the beacons'
    positions as arrays in the line's order. On a line ten times the sample the scans over every restriction
    and beacon for each leg's window were a whole second of the night, and grow with the square of the line."""

    def __init__(self, line: "Line"):
        self.stations: dict = {}
        for st in line.stations:
            self.stations.setdefault(st.station_id, st)
        self.limit_start_m = np.array([x.start_m for x in line.speed_limits], float)
        self.limit_end_m = np.array([x.end_m for x in line.speed_limits], float)
        self.beacon_m = np.array([b.position_m for b in line.beacons], float)
        self._beacons_for: dict = {}

    def beacons_for(self, line: "Line", direction: str) -> tuple[tuple, np.ndarray]:
        """The beacons read in ``direction`` in running order (a stable sort of the line's), and their positions."""
        hit = self._beacons_for.get(direction)
        if hit is None:
            b = tuple(sorted((x for x in line.beacons if x.direction == direction),
                             key=lambda x: sign(direction) * x.position_m))
            hit = self._beacons_for[direction] = (b, np.array([x.position_m for x in b], float))
        return hit


def per_line(fn):
    """``fn(line, *args)`` made once per line object and arguments, then given again: for what several steps of a
    run ask of the same line (a :class:`Line` is immutable; an edited line is another object, with its own). Kept
    beside the line, not in it (a line pickled to a worker or digested carries none), as long as the line lives.
    What ``fn`` gives is shared by every caller: a tuple, a string, or an object nobody changes."""
    made: "weakref.WeakKeyDictionary[Line, dict]" = weakref.WeakKeyDictionary()

    @functools.wraps(fn)
    def once(line, *args):
        by = made.get(line)  # not setdefault: it makes a dict and a weak reference with a callback every call
        if by is None:
            by = made[line] = {}
        got = by.get(args)
        if got is None:
            got = by[args] = fn(line, *args)
        return got
    return once


@per_line
def _index(line: "Line") -> _Index:
    """Each line's :class:`_Index`."""
    return _Index(line)


def _lookup(items, attr: str, text: str, what: str, line_id: str):
    """Exact id, else the unique case-insensitive match; else UnknownNameError with a suggestion."""
    for x in items:
        if getattr(x, attr) == text:
            return x
    ids = [getattr(x, attr) for x in items]
    folded = [x for x in items if str(getattr(x, attr)).casefold() == str(text).casefold()]
    if len(folded) == 1:
        return folded[0]
    raise UnknownNameError(f"unknown {what} {text!r} on line {line_id}{did_you_mean(text, ids)} "
                           f"(known: {', '.join(ids)})")


def did_you_mean(text: str, ids) -> str:
    """``"; did you mean X?"`` for the id closest to ``text`` (case-insensitive), or ``""`` when none is close."""
    import difflib

    ids = [str(i) for i in ids]
    close = difflib.get_close_matches(str(text).upper(), [i.upper() for i in ids], n=1, cutoff=0.5)
    return f"; did you mean {next(i for i in ids if i.upper() == close[0])}?" if close else ""


def line_title(name: str, line_id: str) -> str:
    """``name (line_id)``, without repeating the id when the name already ends with it in brackets."""
    name, line_id = str(name).strip(), str(line_id).strip()
    if not name or name == line_id:
        return line_id
    if name.endswith(f"({line_id})"):
        return name
    return f"{name} ({line_id})"
