"""What OSRD rolling stock gives beyond the line database: a short effort curve, fields not used.

OSRD publishes rolling stock whose effort curve ends below its ``max_speed`` (its
fast test stocks: a curve to 77 m/s, ``max_speed`` 80 m/s) and fields the planner
does not model (start-up acceleration, energy sources, power restrictions, a
``gamma.type`` other than CONST). The importer extends the curve by the rule below
and names every field it does not take in the import summary.
"""
from __future__ import annotations

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
