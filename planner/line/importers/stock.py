"""What OSRD rolling stock gives beyond the line database: a short effort curve, fields not used.

OSRD publishes rolling stock whose effort curve ends below its ``max_speed`` (its
fast test stocks: a curve to 77 m/s, ``max_speed`` 80 m/s) and fields the planner
does not model (start-up acceleration, energy sources, power restrictions, a
``gamma.type`` other than CONST). The importer extends the curve by the rule below
and names every field it does not take in the import summary.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from planner.errors import SourceError
from planner.line.schema import TABLES
from planner.line.importers.common import ImportSummary, braking_note, load_json, number

MAX_SPEED_MS = 100.0
"""Highest plausible railjson speed [m/s] (360 km/h); above it the value was probably given in km/h."""

CURVE_STEP_MS = 1.0
"""Speed step [m/s] of the points added to a short effort curve: the chord of F = P/v over one step
overestimates the hyperbola by at most P·Δv²/(4·v³), i.e. 0.012 % of F at 20 m/s (and less faster)."""


def extend_at_constant_power(speeds: list[float], efforts: list[float], vmax: float) -> list[float]:
    """Append effort points from the curve's last speed to ``vmax`` at the power of its last point (in place).

    Above its last tabulated speed a traction unit is held by its power, not its
    adhesion or current limit: the curve's end is the start of the constant-power
    hyperbola ``F(v) = P / v`` with ``P = F_last · v_last`` [W] (Davis/Hay, the
    "hyperbolic part" of a tractive effort diagram). It never gives more effort
    than the last point (holding the last effort would), so the running times it
    gives are not optimistic. Returns the added speeds [m/s].
    """
    v0, f0 = speeds[-1], efforts[-1]
    n = max(1, int(-(-(vmax - v0) // CURVE_STEP_MS)))
    added = [v0 + (vmax - v0) * k / n for k in range(1, n + 1)]
    added[-1] = vmax
    speeds += added
    efforts += [f0 * v0 / v for v in added]
    return added


_USED_FIELDS = {"name", "length", "mass", "max_speed", "inertia_coefficient", "comfort_acceleration", "const_gamma",
                "gamma", "rolling_resistance", "effort_curves"}
_IDENTITY_FIELDS = {"railjson_version", "id", "version", "locked", "metadata", "loading_gauge", "base_power_class"}
"""Fields that describe the file or gauge, not the running: not worth a line in the summary."""


def unused_fields(rs: dict, mode: str) -> list[str]:
    """What an OSRD rolling stock gives that the line database does not take (named in the summary)."""
    out = [f"{k} = {rs[k]!r}" if not isinstance(rs[k], (dict, list)) else k
           for k in sorted(set(rs) - _USED_FIELDS - _IDENTITY_FIELDS)
           if rs[k] not in (None, [], {}, "")]
    gamma = rs.get("gamma")
    if isinstance(gamma, dict) and gamma.get("type", "CONST") != "CONST":
        out.append(f"gamma.type = {gamma.get('type')!r} (braking is taken as a constant gamma.value)")
    modes = (rs.get("effort_curves") or {}).get("modes") or {}
    other = sorted(m for m in modes if m != mode)
    if other:
        out.append(f"effort curves of modes {', '.join(other)} (the default mode {mode} is used)")
    if (modes.get(mode) or {}).get("curves"):
        out.append(f"the {len(modes[mode]['curves'])} conditional curves of mode {mode} (its default_curve is used)")
    return out


def _r(x: float) -> float:
    return round(x, 9)


def read_rolling_stock(path: str | Path, s: ImportSummary) -> tuple[str, dict, list[dict]]:
    """One OSRD rolling-stock JSON: its name, its rolling_stock row (railway units) and traction rows."""
    fname, rs = load_json(path)
    if not isinstance(rs, dict):
        raise SourceError(f"{fname}: the top level must be a JSON object (OSRD rolling stock)")

    def get(field: str):
        if field not in rs:
            raise SourceError(f"{fname}: {field}: missing (OSRD rolling stock)")
        return rs[field]

    name = get("name")
    if not isinstance(name, str) or not name:
        raise SourceError(f"{fname}: name: must be a non-empty string (it becomes the train type)")
    length = number(get("length"), f"{fname}: length", "metres", positive=True)
    mass = number(get("mass"), f"{fname}: mass", "kilograms", positive=True)
    if mass < 1000:
        raise SourceError(f"{fname}: mass: {mass!r} kg is lighter than a tonne; OSRD masses are in kg, "
                          f"not tonnes")
    vmax = number(get("max_speed"), f"{fname}: max_speed", "m/s", positive=True)
    if vmax > MAX_SPEED_MS:
        raise SourceError(f"{fname}: max_speed: {vmax!r} m/s is {vmax * 3.6:.0f} km/h; OSRD speeds are in "
                          f"m/s: was it given in km/h?")
    inertia = number(get("inertia_coefficient"), f"{fname}: inertia_coefficient")
    if inertia < 1:
        raise SourceError(f"{fname}: inertia_coefficient: {inertia!r} < 1; it is 1 + the rotating-mass "
                          f"factor (e.g. 1.05)")
    comfort = number(get("comfort_acceleration"), f"{fname}: comfort_acceleration", "m/s²", positive=True)
    if "const_gamma" in rs:
        gamma = number(rs["const_gamma"], f"{fname}: const_gamma", "m/s²", positive=True)
    elif isinstance(rs.get("gamma"), dict):
        gamma = number(rs["gamma"].get("value"), f"{fname}: gamma.value", "m/s²", positive=True)
    else:
        raise SourceError(f"{fname}: const_gamma: missing (braking deceleration in m/s², or gamma.value)")
    rr = get("rolling_resistance")
    if not isinstance(rr, dict) or rr.get("type", "davis") != "davis":
        raise SourceError(f"{fname}: rolling_resistance: must be {{\"type\": \"davis\", \"A\", \"B\", \"C\"}}")
    a, b, c = (number(rr.get(k), f"{fname}: rolling_resistance.{k}", "N, N/(m/s), N/(m/s)²") for k in "ABC")
    if min(a, b, c) < 0:
        raise SourceError(f"{fname}: rolling_resistance: A, B and C must be >= 0")
    ec = get("effort_curves")
    mode = ec.get("default_mode") if isinstance(ec, dict) else None
    modes = ec.get("modes") if isinstance(ec, dict) else None
    if not isinstance(modes, dict) or mode not in modes:
        raise SourceError(f"{fname}: effort_curves.default_mode: {mode!r} is not one of effort_curves.modes")
    curve = (modes[mode] or {}).get("default_curve") or {}
    w = f"{fname}: effort_curves.modes.{mode}.default_curve"
    speeds, efforts = curve.get("speeds"), curve.get("max_efforts")
    if not isinstance(speeds, list) or not isinstance(efforts, list) or len(speeds) != len(efforts) \
            or len(speeds) < 2:
        raise SourceError(f"{w}: speeds and max_efforts must be lists of the same length (>= 2)")
    speeds = [number(x, f"{w}.speeds[{k}]", "m/s") for k, x in enumerate(speeds)]
    efforts = [number(x, f"{w}.max_efforts[{k}]", "newtons") for k, x in enumerate(efforts)]
    if speeds[0] != 0 or any(y <= x for x, y in zip(speeds[:-1], speeds[1:])):
        raise SourceError(f"{w}.speeds: must start at 0 and increase strictly")
    if min(efforts) < 0:
        raise SourceError(f"{w}.max_efforts: efforts must be >= 0 N")
    if speeds[-1] < vmax:
        added = extend_at_constant_power(speeds, efforts, vmax)
        s.notes.append(f"{fname}: effort curve ends at {speeds[-1 - len(added)]:g} m/s, below max_speed {vmax:g} "
                       f"m/s: extended at the constant power of its last point (F = F_last·v_last / v), "
                       f"{len(added)} points up to {efforts[-1] / 1000:.3f} kN at max_speed")
    s.unused += [f"{fname}: {u}" for u in unused_fields(rs, mode)]
    kmh = lambda v: _r(v * 3.6)  # noqa: E731
    row = dict(train_type=name, length_m=length, empty_mass_t=_r(mass / 1000),
               full_load_mass_t=None,
               rotating_mass_factor=_r(inertia - 1), max_speed_kmh=kmh(vmax),
               max_accel_kmh_s=None, davis_a_kN=_r(a / 1000), davis_b_kN_per_kmh=_r(b / 1000 / 3.6),
               davis_c_kN_per_kmh2=_r(c / 1000 / 3.6**2), service_brake_kmh_s=None, stop_brake_kmh_s=None,
               atsp_pattern_kmh_s=None, brake_comfort_kmh_s=None,
               jerk_limit_kmh_s2=None, speed_margin_kmh=None, cruise=None, coast_band_kmh=None)
    over = (s.extra.rolling_stock if s.extra else {}).get(name, {})
    # comfort_acceleration is OSRD's traction comfort limit: it caps powering, never braking; the brake is gamma
    derived = {"max_accel_kmh_s": kmh(comfort), "service_brake_kmh_s": kmh(gamma), "stop_brake_kmh_s": kmh(gamma),
               "atsp_pattern_kmh_s": kmh(gamma)}
    for col in ("full_load_mass_t", "max_accel_kmh_s", "brake_comfort_kmh_s", "service_brake_kmh_s", "stop_brake_kmh_s",
                "atsp_pattern_kmh_s", "jerk_limit_kmh_s2", "speed_margin_kmh", "cruise", "coast_band_kmh"):
        if col in over:
            continue
        value = s.default(col, name)
        given = s.extra is not None and col in s.extra.defaults  # [defaults] beats the derived value
        row[col] = value if given else derived.get(col, value)
    row.update(over)
    s.notes.append(braking_note(row, f"{fname} (comfort_acceleration {comfort:g} m/s² -> max_accel_kmh_s, "
                                     f"gamma {gamma:g} m/s² -> service, stop and ATS-P brake)"))
    traction = [dict(train_type=row["train_type"], speed_kmh=kmh(v), effort_kN=_r(f / 1000)) for v, f in zip(speeds, efforts)]
    return name, row, traction


def rolling_stock_tables(paths: list, s: ImportSummary) -> tuple[pd.DataFrame, pd.DataFrame]:
    if not paths:
        raise SourceError(f"{s.source}: --rolling-stock: give at least one OSRD rolling-stock JSON (the "
                          f"line database needs a train type)")
    rows, traction, known = [], [], set()
    for p in paths:
        name, row, tr = read_rolling_stock(p, s)
        if any(r["train_type"] == row["train_type"] for r in rows):
            raise SourceError(f"{Path(p).name}: name: train type {row['train_type']!r} is given twice")
        rows.append(row)
        traction += tr
        known.add(name)
    for k in (s.extra.rolling_stock if s.extra else {}):
        if k not in known:
            raise s.extra.err(f"[rolling_stock.{k}]", f"no train type {k!r}; they are {', '.join(sorted(known))}")
    cols = lambda t: [f.name for f in TABLES[t].schema]  # noqa: E731
    return pd.DataFrame(rows, columns=cols("rolling_stock")), pd.DataFrame(traction, columns=cols("traction"))


# --------------------------------------------------------------------------- entry point
