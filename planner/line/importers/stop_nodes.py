"""Stop nodes for the stations a source gives no platform (added by position, no parts, or only a part on a
switch): without one a train calling there could not be routed, failing the night on data the import
accepted.

Each such station gets a ``stop`` node on the line's own track at its stop marker, and one on every other
main or loop beside it there: a track of :data:`~planner.line.importers.sides.MAIN_M` or more, joined at both
ends, whose chainage spans the marker (placed as :func:`~planner.line.importers.network.network_tables`
places that track's points). So on a double line a train of either direction can stop on its own main, and
on a single line a train can wait in a crossing loop, as at a station whose platforms the source names.
"""
from __future__ import annotations


def stops_on_line(topo, on_line: dict[str, tuple[float, int]], stations, notes: list[str]) -> None:
    """Add the stop points of ``stations`` (``(station_id, chainage)``) that have no platform to ``topo``."""
    from planner.line.importers.network import _key, placed
    from planner.line.importers.sides import MAIN_M

    joins = {_key(t, p) for _, _, members in topo.joins for t, p, _ in members}
    have = {p[4] for p in topo.points if p[1] == "stop" and _key(p[2], p[3]) not in joins}
    added: dict[str, int] = {}
    beside: dict[str, list[str]] = {}
    ends = None
    for sid, x in stations:
        if sid in have:
            continue
        for t, (offset, sign) in sorted(on_line.items()):
            pos = (x - offset) * sign
            if -1e-6 <= pos <= topo.lengths[t] + 1e-6:
                k = added[sid] = added.get(sid, 0) + 1
                topo.points.append((f"STOP-{sid}" + (f"-{k}" if k > 1 else ""), "stop", t,
                                    min(max(pos, 0.0), topo.lengths[t]), sid))
                break
        else:
            continue
        if ends is None:  # where every other track lies, once
            uf, at, keep = placed(topo, on_line)
            ends = {t: (at[uf.find(_key(t, 0.0))], at[uf.find(_key(t, n))], n) for t, n in topo.lengths.items()
                    if t in keep and t not in on_line and n >= MAIN_M
                    and _key(t, 0.0) in joins and _key(t, n) in joins}
        for t, (c0, c1, n) in sorted(ends.items()):
            if min(c0, c1) + 1.0 < x < max(c0, c1) - 1.0:
                name = f"STOP-{sid}-{t}" + (f"-{added[sid]}" if added[sid] > 1 else "")
                topo.points.append((name, "stop", t, (x - c0) / (c1 - c0) * n, sid))
                if t not in beside.setdefault(sid, []):
                    beside[sid].append(t)
    if added:
        notes.append(f"track network: {len(added)} station(s) without a platform in the source ({', '.join(added)}) "
                     "get a stop node on the line's own track at each of their stop markers"
                     + (", and on the tracks beside it there (" + "; ".join(
                         f"{sid}: {', '.join(ts)}" for sid, ts in beside.items()) + ")" if beside else ""))
