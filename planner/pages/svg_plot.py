"""The pages' charts written directly as SVG: linear axes, nice ticks, lines, bars, markers, spans and labels.

Every chart of the pages the nightly job writes is drawn here: the speed–distance chart of every leg
(:mod:`planner.pages.speed_chart`) and the margin report's four (:mod:`planner.pages.margin_charts`).
matplotlib's text layout, legends, ticks and ``savefig`` cost ~80 ms a chart and the data nothing (and
importing it ~0.3 s of CPU in every process that draws); here a chart is a few hundred strings joined,
a few milliseconds. What it gives up is text metrics: a label's box is
sized from an estimate of the text's width (:func:`text_width`), so a legend is not drawn in the SVG but
written in HTML beside it (:func:`legend_html`), where the browser lays it out.

A :class:`Figure` of ``width`` × ``height`` user units (its ``viewBox``; it scales to the width of its box,
``width="100%"``) holds :class:`Panel` s, each a plot frame at a fixed place with linear x and y axes
(:class:`Scale`, x reversible: a run in the ``up`` direction runs left to right), grid and ticks at
nice numbers (:func:`nice_ticks`: 1, 2, 2.5 or 5 × 10ⁿ), limits padded as matplotlib's autoscale does
(:func:`padded`). Panels may share x limits (panels stacked) or y limits (side by side, the tick labels
on the first only). A panel draws lines, steps, fills, bars (:meth:`Panel.rects`, each with its tooltip),
markers, bands and labels, and may carry its own title and labelled ticks along its top edge (station
codes). Everything drawn in data coordinates is clipped to its panel.

Output is deterministic and small: coordinates rounded to 0.1 unit (:func:`num`), consecutive
points that round to the same place written once, ids fixed by the caller (no random or hash-salted
ids), every text escaped for XML (:func:`esc`), so ``xml.etree`` parses the result.

Example::

    fig = Figure(600, 300)
    p = fig.panel((50, 20, 530, 240), (0.0, 10.0), (0.0, 100.0), xlabel="km", ylabel="km/h")
    p.polyline([0, 5, 10], [0, 80, 0], color="#1f5fa8", width=1.8)
    svg = fig.svg()
"""
from __future__ import annotations

import html
import math
import re

import numpy as np

FONT = "system-ui,-apple-system,'Segoe UI',Roboto,Helvetica,Arial,sans-serif"
"""The pages' font (``planner.pages.margin_report.CSS``), so the chart's text matches the page's."""


def esc(s: str) -> str:
    """``s`` escaped for XML text and attribute values (``& < > " '``)."""
    return html.escape(str(s), quote=True)


def num(v: float) -> str:
    """A coordinate rounded to 0.1 unit, shortest form, never ``-0``."""
    r = round(float(v), 1) + 0.0
    return str(int(r)) if r == int(r) else f"{r:.1f}"


_WHOLE = re.compile(r"\.0(?=[, ]|$)")
"""The ``.0`` of a whole number in a points list (every value there has one decimal at most)."""


def _pairs(px: np.ndarray, py: np.ndarray) -> str:
    """``x,y x,y …`` of points in user units, a point that rounds onto the one before dropped: :func:`num` of each.

    A value rounded to 0.1 is the double nearest a count of tenths, and the shortest string that reads back as
    that double (``repr``) is that count's decimal: :func:`num`'s ``.1f``, with ``.0`` where :func:`num` writes a
    whole number, so the ``.0`` are cut from the joined list. The list is made without a Python call per point
    (a chart has thousands). ``repr`` writes an exponent from 1e16, far outside any page: past 1e15 each value
    is written by :func:`num` itself."""
    px, py = np.round(np.asarray(px, float), 1) + 0.0, np.round(np.asarray(py, float), 1) + 0.0
    if len(px) > 2:
        keep = np.ones(len(px), bool)
        keep[1:] = (px[1:] != px[:-1]) | (py[1:] != py[:-1])
        px, py = px[keep], py[keep]
    if len(px) and max(np.abs(px).max(), np.abs(py).max()) >= 1e15:
        return " ".join(f"{num(a)},{num(b)}" for a, b in zip(px.tolist(), py.tolist()))
    xy = np.empty(2 * len(px))
    xy[0::2], xy[1::2] = px, py
    each = iter(map(repr, xy.tolist()))
    return _WHOLE.sub("", " ".join(map(",".join, zip(each, each))))


def nice_ticks(lo: float, hi: float, target: int = 6) -> tuple[list[float], int]:
    """Tick values in [lo, hi] at a step of 1, 2, 2.5 or 5 × 10ⁿ, the smallest such step giving at most
    ``target`` intervals over the span, and the decimals their labels need."""
    span = hi - lo
    if not (span > 0 and math.isfinite(span)):
        return [lo], 0
    raw = span / max(target, 1)
    mag = 10.0 ** math.floor(math.log10(raw))
    for m in (1.0, 2.0, 2.5, 5.0, 10.0):
        step = m * mag
        if step >= raw * (1 - 1e-9):
            break
    first = math.ceil(lo / step - 1e-9)
    ticks = [round(k * step, 12) + 0.0 for k in range(first, math.floor(hi / step + 1e-9) + 1)]
    dec = next(k for k in range(12) if abs(step * 10 ** k - round(step * 10 ** k)) < 1e-6)  # 25: 0, 0.25: 2
    return ticks, dec


def padded(lo: float, hi: float, frac: float = 0.05) -> tuple[float, float]:
    """Axis limits around data from ``lo`` to ``hi``: ``frac`` of the span added at each end (matplotlib's
    autoscale margins); a single value gets ±0.5 (±5 % of itself when large), no data (NaN) (0, 1)."""
    lo, hi = float(lo), float(hi)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return 0.0, 1.0
    if hi <= lo:
        m = max(0.5, 0.05 * abs(lo))
        return lo - m, lo + m
    m = frac * (hi - lo)
    return lo - m, hi + m


_WIDTHS = {" ": 0.32, ".": 0.32, ",": 0.32, ":": 0.34, "(": 0.39, ")": 0.39, "-": 0.36, "/": 0.34, "|": 0.34,
           "i": 0.28, "l": 0.28, "j": 0.28, "I": 0.3, "f": 0.35, "t": 0.39, "r": 0.41, "m": 0.97, "w": 0.82,
           "M": 0.86, "W": 0.99}


def text_width(s: str, size: float, bold: bool = False) -> float:
    """An estimate of the width of ``s`` at font size ``size`` (a sans-serif's advance widths: capitals and
    digits ~0.64–0.75 em, lower case ~0.56 em), on the wide side; for a box around a label."""
    w = sum(_WIDTHS.get(c, 0.72 if c.isupper() else 0.64 if c.isdigit() else 0.58) for c in s)
    return w * size * (1.07 if bold else 1.0)


def _dash(dash) -> str:
    return f' stroke-dasharray="{" ".join(num(d) for d in dash)}"' if dash else ""


def _opacity(name: str, v) -> str:
    return f' {name}="{v:g}"' if v is not None else ""


class Scale:
    """The linear map of data values [lo, hi] onto user units [p_lo, p_hi] (p_hi < p_lo: a y axis, or a
    reversed x axis)."""

    def __init__(self, lo: float, hi: float, p_lo: float, p_hi: float):
        self.lo, self.hi, self.p_lo, self.p_hi = float(lo), float(hi), float(p_lo), float(p_hi)
        self.k = (self.p_hi - self.p_lo) / (self.hi - self.lo) if self.hi != self.lo else 0.0

    def __call__(self, v):
        return self.p_lo + (np.asarray(v, float) - self.lo) * self.k


class Panel:
    """A plot frame at ``box`` = (left, top, width, height) with x limits ``xlim`` and y limits ``ylim``
    (data units); ``x_inverted``: x grows to the left; ``xticks``/``yticks``: label the ticks (a panel sharing
    the axis of another leaves them to it); ``grid``: ``both``, ``x``, ``y`` or ``None``; ``ylabel`` may
    hold ``\n`` (one line each, the last nearest the axis). Draw with the methods below (data coordinates),
    then :meth:`Figure.svg` writes grid, data (clipped to the frame), frame, ticks and labels."""

    def __init__(self, index: int, box, xlim, ylim, *, x_inverted=False, xlabel="", ylabel="", xticks=True,
                 yticks=True, xtarget=10, ytarget=6, grid="both", font: float = 10):
        self.index, self.box, self.font = index, tuple(float(b) for b in box), float(font)
        left, top, w, h = self.box
        self.xlim, self.ylim = tuple(map(float, xlim)), tuple(map(float, ylim))
        self.x = Scale(*self.xlim, left + w, left) if x_inverted else Scale(*self.xlim, left, left + w)
        self.y = Scale(*self.ylim, top + h, top)
        self.xlabel, self.ylabel, self.xticks, self.yticks, self.grid = xlabel, ylabel, xticks, yticks, grid
        self.targets = (xtarget, ytarget)
        self.data: list[str] = []
        self.labels: list[str] = []

    # --- data, clipped to the frame -----------------------------------------------------------------------------
    def polyline(self, x, y, *, color: str, width: float = 1.0, dash=None, opacity=None):
        """A line through (x, y), broken where a value is not finite (NaN: no value there, as matplotlib)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        ok = np.isfinite(x) & np.isfinite(y)
        if not ok.all():  # each finite run on its own
            cuts = np.flatnonzero(np.diff(ok.astype(np.int8))) + 1
            for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(x)]):
                if ok[a]:
                    self.polyline(x[a:b], y[a:b], color=color, width=width, dash=dash, opacity=opacity)
            return
        if len(x):
            self.data.append(f'<polyline points="{_pairs(self.x(x), self.y(y))}" fill="none" stroke="{color}" '
                             f'stroke-width="{width:g}"{_dash(dash)}{_opacity("stroke-opacity", opacity)}/>')

    def steps_mid(self, x, y, **style):
        """A step line, each y held from halfway after the point before to halfway before the point after
        (matplotlib's ``step(where="mid")``); only the steps are written, not every point of a flat run."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        if len(x) < 2:
            return self.polyline(x, y, **style)
        ch = np.flatnonzero(y[1:] != y[:-1])  # y changes between point i and i + 1
        mid = 0.5 * (x[ch] + x[ch + 1])
        sx = np.concatenate([[x[0]], np.repeat(mid, 2), [x[-1]]])
        sy = np.concatenate([[y[0]], np.column_stack([y[ch], y[ch + 1]]).ravel(), [y[-1]]])
        self.polyline(sx, sy, **style)

    def fill_between(self, x, y0, y1, *, color: str, opacity=None, edge_width: float = 0.0):
        """The area between the lines (x, y0) and (x, y1)."""
        x = np.asarray(x, float)
        if not len(x):
            return
        y0, y1 = np.broadcast_to(np.asarray(y0, float), x.shape), np.asarray(y1, float)
        px, py = np.concatenate([x, x[::-1]]), np.concatenate([y1, y0[::-1]])
        edge = f' stroke="{color}" stroke-width="{edge_width:g}"' if edge_width else ""
        self.data.append(f'<polygon points="{_pairs(self.x(px), self.y(py))}" fill="{color}"'
                         f'{_opacity("fill-opacity", opacity)}{edge}{_opacity("stroke-opacity", opacity)}/>')

    def span(self, x0: float, x1: float, *, fill: str, opacity=None, y0=None, y1=None):
        """A band from x0 to x1, from y0 to y1 (data; ``None``: the frame's edge); ``fill`` may be a pattern,
        ``url(#id)`` (:meth:`Figure.hatch`)."""
        a, b = sorted(float(v) for v in self.x([x0, x1]))
        top = self.box[1] if y1 is None else float(self.y(y1))
        bot = self.box[1] + self.box[3] if y0 is None else float(self.y(y0))
        self.data.append(f'<rect x="{num(a)}" y="{num(top)}" width="{num(b - a)}" height="{num(bot - top)}" '
                         f'fill="{fill}"{_opacity("fill-opacity", opacity)}/>')

    def rects(self, x0, x1, y0, y1, *, fill: str, stroke: str | None = None, width: float = 0.6, opacity=None,
              tips=None):
        """Boxes from (x0[i], y0[i]) to (x1[i], y1[i]) (data; either corner first): bars. ``tips``: a text per
        box, its tooltip (an SVG ``<title>``). A box with a value that is not finite is not drawn."""
        x0, x1, y0, y1 = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, float)) for v in (x0, x1, y0, y1)))
        tips = [None] * len(x0) if tips is None else list(tips)
        ok = np.isfinite(x0) & np.isfinite(x1) & np.isfinite(y0) & np.isfinite(y1)
        x0, x1, y0, y1 = self.x(x0[ok]), self.x(x1[ok]), self.y(y0[ok]), self.y(y1[ok])
        tips = [t for t, k in zip(tips, ok.tolist()) if k]
        edge = f' stroke="{stroke}" stroke-width="{width:g}"' if stroke else ""
        paint = f'fill="{fill}"{_opacity("fill-opacity", opacity)}{edge}'
        for a, b, c, d, tip in zip(np.minimum(x0, x1).tolist(), np.maximum(x0, x1).tolist(),
                                   np.minimum(y0, y1).tolist(), np.maximum(y0, y1).tolist(), tips):
            rect = f'<rect x="{num(a)}" y="{num(c)}" width="{num(b - a)}" height="{num(d - c)}" {paint}'
            self.data.append(f"{rect}><title>{esc(tip)}</title></rect>" if tip else f"{rect}/>")

    def vline(self, x: float, *, color: str, width: float = 1.0, dash=None):
        """A vertical line across the frame at x (none where x is not finite: a missing value)."""
        if not np.isfinite(x):
            return
        px, (_, top, _, h) = num(self.x(x)), self.box
        self.data.append(f'<line x1="{px}" y1="{num(top)}" x2="{px}" y2="{num(top + h)}" stroke="{color}" '
                         f'stroke-width="{width:g}"{_dash(dash)}/>')

    def hline(self, y: float, *, color: str, width: float = 1.0, dash=None):
        """A horizontal line across the frame at y (none where y is not finite: a missing value)."""
        if not np.isfinite(y):
            return
        py, (left, _, w, _) = num(self.y(y)), self.box
        self.data.append(f'<line x1="{num(left)}" y1="{py}" x2="{num(left + w)}" y2="{py}" stroke="{color}" '
                         f'stroke-width="{width:g}"{_dash(dash)}/>')

    def markers(self, x, y, shape: str, *, size: float, fill: str, stroke: str | None = None, width: float = 1.0):
        """A marker at each (x, y), one path: ``shape`` ``v`` (triangle down), ``D`` (diamond), ``|`` (tick),
        ``o`` (circle); ``size`` its height in user units."""
        s = size / 2
        rel = {"v": f"m{num(-s)},{num(-s)}h{num(size)}l{num(-s)},{num(size)}z",
               "o": f"m{num(-s)},0a{num(s)},{num(s)} 0 1,0 {num(size)},0a{num(s)},{num(s)} 0 1,0 {num(-size)},0z",
               "D": f"m0,{num(-s)}l{num(s * 0.75)},{num(s)}l{num(-s * 0.75)},{num(s)}l{num(-s * 0.75)},{num(-s)}z",
               "|": f"m0,{num(-s)}v{num(size)}"}[shape]
        x, y = np.asarray(x, float), np.asarray(y, float)
        ok = np.isfinite(x) & np.isfinite(y)  # no marker where there is no value
        d = "".join(f"M{num(a)},{num(b)}{rel}" for a, b in zip(self.x(x[ok]).tolist(), self.y(y[ok]).tolist()))
        if not d:
            return
        paint = (f'fill="none" stroke="{fill}" stroke-width="{width:g}"' if shape == "|" else
                 f'fill="{fill}"' + (f' stroke="{stroke}" stroke-width="{width:g}"' if stroke else ""))
        self.data.append(f'<path d="{d}" {paint}/>')

    # --- labels, over the data, not clipped ---------------------------------------------------------------------
    def text(self, x: float, y: float, lines, *, size: float = 9, color: str = "#1d2327", anchor: str = "middle",
             va: str = "top", bold: bool = False, box: tuple[str, str] | None = None, x_frac: bool = False,
             y_frac: bool = False, dx: float = 0.0, dy: float = 0.0):
        """A label at data (x, y) (``x_frac``/``y_frac``: x or y as a fraction of the frame's width from the left
        or height from the bottom), moved by (dx, dy) user units (y down): ``lines`` a string or several; ``va``
        which side of the text is at y (``top``, ``bottom``); ``box``: (fill, stroke) of a rounded box around
        it, sized by :func:`text_width`). Nothing is drawn where x or y is not finite (a missing value)."""
        if not (np.isfinite(x) and np.isfinite(y)):
            return
        lines = [lines] if isinstance(lines, str) else list(lines)
        px = (self.box[0] + self.box[2] * x if x_frac else float(self.x(x))) + dx
        py = (self.box[1] + self.box[3] * (1 - y) if y_frac else float(self.y(y))) + dy
        lh = 1.2 * size
        pad = 0.3 * size if box else 0.0
        h = lh * len(lines)
        top = py + pad if va == "top" else py - pad - h
        out = []
        if box:
            tw = max(text_width(s, size, bold) for s in lines)
            left = {"start": px, "middle": px - tw / 2, "end": px - tw}[anchor] - pad
            out.append(f'<rect x="{num(left)}" y="{num(top - pad)}" width="{num(tw + 2 * pad)}" height="{num(h + 2 * pad)}" '
                       f'rx="{num(0.35 * size)}" fill="{box[0]}" stroke="{box[1]}" stroke-width="0.6"/>')
        spans = "".join(f'<tspan x="{num(px)}" y="{num(top + lh * (k + 0.8))}">{esc(s)}</tspan>'
                        for k, s in enumerate(lines))
        weight = ' font-weight="bold"' if bold else ""
        out.append(f'<text font-size="{size:g}" fill="{color}" text-anchor="{anchor}"{weight}>{spans}</text>')
        self.labels.append("".join(out))

    def title(self, s: str, *, loc: str = "left", size: float = 11, bold: bool = True, pad: float = 7.0):
        """A line of text over the frame (``loc`` ``left`` or ``center``), its baseline ``pad`` above it."""
        left, top, w, _ = self.box
        x, anchor = (left, "start") if loc == "left" else (left + w / 2, "middle")
        weight = ' font-weight="bold"' if bold else ""
        self.labels.append(f'<text x="{num(x)}" y="{num(top - pad)}" font-size="{size:g}" text-anchor="{anchor}"'
                           f'{weight}>{esc(s)}</text>')

    def top_ticks(self, x, labels, *, size: float = 9):
        """Ticks on the frame's top edge at data x, each with its label over it (station codes)."""
        top = self.box[1]
        px = [num(v) for v in self.x(np.asarray(x, float)).tolist()]
        marks = "".join(f"M{a},{num(top)}v-4" for a in px)
        text = "".join(f'<text x="{a}" y="{num(top - 7)}" text-anchor="middle">{esc(s)}</text>'
                       for a, s in zip(px, labels))
        self.labels.append(f'<path d="{marks}" stroke="#222" stroke-width="0.8"/>'
                           f'<g font-size="{size:g}" fill="#222">{text}</g>')

    # --- frame ----------------------------------------------------------------------------------------------------
    def _axes(self) -> tuple[str, str]:
        """(grid, frame with ticks and axis labels)."""
        left, top, w, h = self.box
        bottom = top + h
        grid, frame = [], []
        xt, xdec = nice_ticks(*self.xlim, self.targets[0])
        yt, ydec = nice_ticks(*self.ylim, self.targets[1])
        for t in xt:
            px = num(self.x(t))
            if self.grid in ("both", "x"):
                grid.append(f"M{px},{num(top)}V{num(bottom)}")
            frame.append(f"M{px},{num(bottom)}v4")
        for t in yt:
            py = num(self.y(t))
            if self.grid in ("both", "y"):
                grid.append(f"M{num(left)},{py}H{num(left + w)}")
            frame.append(f"M{num(left)},{py}h-4")
        text = []
        f = self.font / 10.0  # offsets grow with the font (laid out for 10)
        if self.xticks:
            text += [f'<text x="{num(self.x(t))}" y="{num(bottom + 6 + 10 * f)}" text-anchor="middle">'
                     f'{t:.{xdec}f}</text>' for t in xt]
        if self.yticks:
            text += [f'<text x="{num(left - 7)}" y="{num(float(self.y(t)) + 3.5 * f)}" text-anchor="end">'
                     f'{(t + 0.0):.{ydec}f}</text>' for t in yt]
        if self.xlabel:
            text.append(f'<text x="{num(left + w / 2)}" y="{num(bottom + 10 + 24 * f)}" text-anchor="middle">'
                        f'{esc(self.xlabel)}</text>')
        if self.ylabel:
            rows = self.ylabel.split("\n")
            cx, cy = num(left - 14 - 30 * f - 12 * f * (len(rows) - 1)), num(top + h / 2)
            body = "".join(f'<tspan x="{cx}" dy="{0 if k == 0 else num(12 * f)}">{esc(s)}</tspan>'
                           for k, s in enumerate(rows))
            text.append(f'<text x="{cx}" y="{cy}" text-anchor="middle" transform="rotate(-90 {cx} {cy})">'
                        f'{body if len(rows) > 1 else esc(self.ylabel)}</text>')
        return (f'<path d="{"".join(grid)}" stroke="#e3e3e3" stroke-width="0.8"/>' if grid else "",
                f'<rect x="{num(left)}" y="{num(top)}" width="{num(w)}" height="{num(h)}" fill="none" stroke="#222" '
                f'stroke-width="0.8"/><path d="{"".join(frame)}" stroke="#222" stroke-width="0.8"/>'
                f'<g font-size="{self.font:g}" fill="#222">{"".join(text)}</g>')


class Figure:
    """A chart of ``width`` × ``height`` user units holding panels; ``ident`` prefixes its ids (clip paths,
    patterns), so that two charts on one page stay apart."""

    def __init__(self, width: float, height: float, *, ident: str = "c"):
        self.width, self.height, self.ident = width, height, ident
        self.panels: list[Panel] = []
        self.defs: list[str] = []
        self.top: list[str] = []

    def panel(self, box, xlim, ylim, **kw) -> Panel:
        """A new panel (:class:`Panel`), drawn in the order made."""
        p = Panel(len(self.panels), box, xlim, ylim, **kw)
        self.panels.append(p)
        return p

    def hatch(self, name: str, *, fill: str, stroke: str, spacing: float = 7.0, width: float = 1.2) -> str:
        """A fill of diagonal lines (``//``) over ``fill``; returns the ``url(#…)`` to give as a fill."""
        pid = f"{self.ident}-{name}"
        s = num(spacing)
        self.defs.append(f'<pattern id="{pid}" patternUnits="userSpaceOnUse" width="{s}" height="{s}" '
                         f'patternTransform="rotate(45)"><rect width="{s}" height="{s}" fill="{fill}"/>'
                         f'<line x1="0" y1="0" x2="0" y2="{s}" stroke="{stroke}" stroke-width="{width:g}"/></pattern>')
        return f"url(#{pid})"

    def title(self, x: float, y: float, s: str, *, size: float = 14, bold: bool = True, color: str | None = None):
        """A line of text at (x, y) user units (left end, baseline)."""
        weight = ' font-weight="bold"' if bold else ""
        fill = f' fill="{color}"' if color else ""
        self.top.append(f'<text x="{num(x)}" y="{num(y)}" font-size="{size:g}"{weight}{fill}>{esc(s)}</text>')

    def svg(self, *, label: str = "") -> str:
        """The ``<svg>`` element (``label``: its ``aria-label``)."""
        out = [f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {num(self.width)} {num(self.height)}" '
               f'width="100%" role="img" aria-label="{esc(label)}" font-family="{FONT}" fill="#1d2327">']
        clips = [f'<clipPath id="{self.ident}-clip{p.index}"><rect x="{num(p.box[0])}" y="{num(p.box[1])}" '
                 f'width="{num(p.box[2])}" height="{num(p.box[3])}"/></clipPath>' for p in self.panels]
        out.append(f"<defs>{''.join(clips + self.defs)}</defs>")
        for p in self.panels:
            grid, frame = p._axes()
            out += [grid, f'<g clip-path="url(#{self.ident}-clip{p.index})">{"".join(p.data)}</g>', frame]
        for p in self.panels:  # labels over every panel's data
            out += p.labels
        out += self.top
        out.append("</svg>")
        return "".join(out)


def swatch(kind: str, *, color: str, width: float = 1.5, dash=None, opacity=None, shape: str = "", edge=None,
           hatch: str | None = None) -> str:
    """A legend's sample as a small inline SVG (28 × 12 px): ``kind`` ``line`` (a stroke, ``dash``), ``marker``
    (``shape`` as :meth:`Panel.markers`, ``edge`` its outline; ``o``: on a line) or ``patch`` (a filled box, ``hatch`` the
    colour of diagonal lines over it)."""
    if kind == "line":
        body = (f'<line x1="1" y1="6" x2="27" y2="6" stroke="{color}" stroke-width="{width:g}"{_dash(dash)}'
                f'{_opacity("stroke-opacity", opacity)}/>')
    elif kind == "marker":
        body = {"v": f'<path d="M10,2.5h8l-4,7z" fill="{color}"/>',
                "D": f'<path d="M14,2l3,4l-3,4l-3,-4z" fill="{color}" stroke="{edge or color}" stroke-width="1"/>',
                "o": f'<line x1="1" y1="6" x2="27" y2="6" stroke="{color}" stroke-width="{width:g}"/>'
                     f'<circle cx="14" cy="6" r="2.6" fill="{color}"/>',
                "|": f'<path d="M14,1.5v9" stroke="{color}" stroke-width="{width:g}"/>'}[shape]
    else:
        lines = (f'<path d="M2,12l10,-10M9,12l10,-10M16,12l10,-10" stroke="{hatch}" stroke-width="1.1"/>'
                 if hatch else "")
        body = f'<rect x="1" y="1" width="26" height="10" fill="{color}"{_opacity("fill-opacity", opacity)}/>{lines}'
    return f'<svg class="sw" xmlns="http://www.w3.org/2000/svg" viewBox="0 0 28 12" width="28" height="12">{body}</svg>'


LEGEND_CSS = (".legend{display:flex;flex-wrap:wrap;gap:2px 18px;margin:6px 4px 2px;font-size:12.5px;color:#333}"
              ".legend span{white-space:nowrap}.fig .legend svg.sw{width:28px;height:12px;display:inline-block;"
              "vertical-align:-1px;margin-right:5px}")
"""The legend's style (:func:`legend_html`), for the page's ``<style>`` (class ``legend``: the margin report's leg
cells are ``lg``, and took the legend's flex box)."""


def legend_html(items, head: str = "") -> str:
    """A legend in HTML: ``items`` (swatch from :func:`swatch`, label), laid out by the browser (wraps on a
    narrow screen), after ``head`` in bold when given (which panel it is for). Labels are escaped."""
    return ('<div class="legend">' + (f"<b>{esc(head)}</b>" if head else "")
            + "".join(f"<span>{sw}{esc(label)}</span>" for sw, label in items) + "</div>")


__all__ = ["Figure", "Panel", "Scale", "nice_ticks", "padded", "text_width", "esc", "num", "swatch", "legend_html",
           "LEGEND_CSS"]
