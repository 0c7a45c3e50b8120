"""Which direction each imported track serves: its signals, the source's own direction, the side trains run on.

The route search keeps a train to the tracks of its direction (``edges.direction``: down, up or both). An
importer decides each track's direction from what the source says, in this order:

1. the import's ``--extra`` ``[track_directions]`` (source track id → down, up or both), where given;
2. the source's own direction attribute of a track (railML ``<track mainDir>``), where it has one;
3. the signals on the track: ``down`` where signals facing down outnumber those facing up two to one,
   ``up`` the other way round, else ``both``. Counted on the track and the tracks linked end to end to it
   when they hold :data:`OWN_SIGNALS` or more, else over its group (tracks joined end to end by links; the
   line's own tracks are one group): counted over the whole line only, a double line whose path takes the
   down main here and the up main there was ``both`` throughout, and trains of both directions met head on;
4. the side trains run on (``line.running_side``: right or left) where two parallel tracks are both still
   ``both`` (a double line signalled alike both ways): facing down, the track on the running side is the
   down main and the other the up main. Only tracks of :data:`MAIN_M` or more joined at both ends: a
   terminus's platforms (ending at buffer stops) stay both; a crossing loop of a single line is run on the
   running side, as railways do. The side is the line's ``[line] running_side`` where given, else the data's
   own: where a down track and an up track run side by side, the side the down track lies on.

Geometry is the source's track coordinates (railjson ``geo``; longitude and latitude are turned into metres
around the network's mean latitude). Two tracks run side by side where points at a quarter, half and three
quarters of one lie 1.5–40 m to the same side of the other, which runs the same way there.
"""
from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from planner.errors import SourceError

OWN_SIGNALS = 3
"""Signals a track needs to be named by its own; with fewer its group's decide."""
MAIN_M = 300.0
"""A track shorter than this is a switch's leg or a crossover, never a main or a loop for the running side [m]."""
SIDE_M = (1.5, 40.0)
"""Lateral distance of two tracks side by side [m]: more than a track's own width, less than a station's."""


def _key(track: str, pos: float) -> tuple[str, float]:
    return track, round(float(pos), 6)


def orientation(topo, on_line: dict, pos: dict, uf, t: str) -> int | None:
    """+1 where track ``t``'s positions grow with the line's chainage, -1 where they fall, None: unplaced."""
    if t in on_line:
        return on_line[t][1]
    a, b = pos.get(uf.find(_key(t, 0.0))), pos.get(uf.find(_key(t, topo.lengths[t])))
    if a is None or b is None or a == b:
        return None
    return 1 if b > a else -1


def track_labels(topo, on_line: dict, own, tuf, pos: dict, uf, running_side: str | None,
                 notes: list[str]) -> tuple[dict[str, str], dict[str, str], str | None]:
    """``(name, direction, side)``: each source track's name (``D:``/``U:``/``B:`` + its group's first track id),
    its direction (down, up, both), and the running side used (given, from the data, or None)."""
    sgn = {t: orientation(topo, on_line, pos, uf, t) for t in topo.lengths}
    faces: dict = defaultdict(lambda: {"down": 0, "up": 0})
    for t, _, along in topo.signals:
        if sgn.get(t) is None:
            continue
        way = "down" if (sgn[t] > 0) == along else "up"
        faces[("own", own.find(t))][way] += 1
        faces[("group", tuf.find(t))][way] += 1
    way: dict[str, str] = {}
    for t in topo.lengths:
        f = faces.get(("own", own.find(t)), {"down": 0, "up": 0})
        if f["down"] + f["up"] < OWN_SIGNALS:
            f = faces.get(("group", tuf.find(t)), {"down": 0, "up": 0})
        way[t] = ("down" if f["down"] > 0 and f["down"] >= 2 * f["up"] else
                  "up" if f["up"] > 0 and f["up"] >= 2 * f["down"] else "both")
    said = 0
    for t, d in getattr(topo, "main_dir", {}).items():
        if t in way and sgn.get(t) is not None:
            way[t] = "both" if d == "both" else "down" if (d == "along") == (sgn[t] > 0) else "up"
            said += 1
    if said:
        notes.append(f"track directions: {said} track(s) as the source's own direction attribute says")
    unknown = sorted(set(topo.given_dir) - {t.split("#")[0] for t in topo.lengths})
    if unknown:
        raise SourceError(f"--extra [track_directions]: {', '.join(unknown)} name(s) no track of the source; use "
                          f"the source's track ids (railjson track section ids, railML <track> ids)")
    given = {t: d for t in way if (d := topo.given_dir.get(t.split("#")[0]))}  # railML pieces: <track id>#k
    way.update(given)
    if given:
        notes.append(f"track directions: {len({t.split('#')[0] for t in given})} source track(s) as "
                     f"[track_directions] says")
    side = _running_side(topo, sgn, way, running_side, notes, set(given))
    name = {t: f"{'D' if w == 'down' else 'U' if w == 'up' else 'B'}:{tuf.find(t)}" for t, w in way.items()}
    return name, way, side


def _running_side(topo, sgn: dict, way: dict, given: str | None, notes: list[str], fixed: set) -> str | None:
    """The running side (given, or the data's), and ``way`` changed for pairs of parallel ``both`` tracks (not
    those in ``fixed``: their direction was given)."""
    joined = {_key(t, p) for _, _, members in topo.joins for t, p, _ in members}
    through = {t for t, n in topo.lengths.items()
               if n >= MAIN_M and _key(t, 0.0) in joined and _key(t, n) in joined}
    geo = {t: xy for t, xy in _metres(getattr(topo, "geo", {})).items() if sgn.get(t) is not None and t in through}
    pairs = _side_by_side(geo, sgn)
    votes = {"right": 0, "left": 0}
    for t, u, left in pairs:
        if way[t] == "down" and way[u] == "up":
            votes["left" if left else "right"] += 1
    side = given
    if side is None and votes["right"] != votes["left"]:
        side = max(votes, key=votes.get)
        notes.append(f"running side {side} (from the data: a down track lies {side} of an up track beside it "
                     f"{votes[side]} time(s), {votes['left' if side == 'right' else 'right']} the other way)")
    if side is None:
        return None
    was_both = {t for t, w in way.items() if w == "both" and t not in fixed}
    lies: dict[str, set] = defaultdict(set)  # the sides a both-ways track lies on of another beside it
    for t, u, left in pairs:
        if t in was_both and u in was_both:
            lies[t].add(left)
    turned = sorted(t for t, sides in lies.items() if len(sides) == 1)  # the middle one of three stays both
    for t in turned:
        way[t] = "down" if next(iter(lies[t])) == (side == "left") else "up"
    if turned:
        notes.append(f"track directions: {len(turned)} track(s) beside another signalled alike both ways named by "
                     f"the running side ({side}): {', '.join(turned[:6])}"
                     f"{' …' if len(turned) > 6 else ''}")
    return side


def _metres(geo: dict[str, list]) -> dict[str, np.ndarray]:
    """Track coordinates in metres: longitude/latitude (every value within ±180/±90) around the mean latitude."""
    arrays = {t: np.asarray(c, dtype=float).reshape(-1, 2) for t, c in geo.items() if c is not None and len(c) >= 2}
    if not arrays:
        return {}
    every = np.vstack(list(arrays.values()))
    if np.all(np.abs(every[:, 0]) <= 180) and np.all(np.abs(every[:, 1]) <= 90):
        lat0 = math.radians(float(every[:, 1].mean()))
        scale = np.array([111_320.0 * math.cos(lat0), 110_574.0])
        return {t: a * scale for t, a in arrays.items()}
    return arrays


def _along(xy: np.ndarray, f: float) -> np.ndarray:
    """The point a fraction ``f`` of the way along polyline ``xy``."""
    seg = np.hypot(*np.diff(xy, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = f * cum[-1]
    j = min(int(np.searchsorted(cum, s, side="right")) - 1, len(seg) - 1)
    r = 0.0 if seg[j] == 0 else (s - cum[j]) / seg[j]
    return xy[j] + r * (xy[j + 1] - xy[j])


def _offset(p: np.ndarray, xy: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Distance of ``p`` from polyline ``xy``, the cross product's sign (> 0: left of its way) and its tangent."""
    a, b = xy[:-1], xy[1:]
    d = b - a
    ll = np.maximum((d * d).sum(axis=1), 1e-12)
    r = np.clip(((p - a) * d).sum(axis=1) / ll, 0.0, 1.0)
    q = a + r[:, None] * d
    dist = np.hypot(*(p - q).T)
    j = int(np.argmin(dist))
    tan = d[j] / math.sqrt(ll[j])
    cross = tan[0] * (p - q[j])[1] - tan[1] * (p - q[j])[0]
    return float(dist[j]), float(cross), tan


def _side_by_side(geo: dict[str, np.ndarray], sgn: dict) -> list[tuple[str, str, bool]]:
    """``(t, u, left)`` for tracks ``t`` running beside ``u`` the same way (both facing down): ``left`` when
    ``t`` lies left of ``u``."""
    down = {t: (xy if sgn[t] > 0 else xy[::-1]) for t, xy in geo.items()}
    box = {t: (xy.min(axis=0) - SIDE_M[1], xy.max(axis=0) + SIDE_M[1]) for t, xy in down.items()}
    out = []
    for t in sorted(down):
        pts = [_along(down[t], f) for f in (0.25, 0.5, 0.75)]
        own = down[t][-1] - down[t][0]
        for u in sorted(down):
            lo, hi = box[u]
            if u == t or not all(np.all(p >= lo) and np.all(p <= hi) for p in pts):
                continue
            seen = [_offset(p, down[u]) for p in pts]
            if not all(SIDE_M[0] <= d <= SIDE_M[1] and float(own @ tan) > 0 for d, _, tan in seen):
                continue
            signs = {c > 0 for _, c, _ in seen}
            if len(signs) == 1:
                out.append((t, u, signs.pop()))
    return out
