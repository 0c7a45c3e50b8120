"""The margin-time report as one self-contained HTML page (DESIGN §6, §9).

:func:`render_html` turns a :class:`planner.report.margins.MarginReport` into a
single HTML document that needs no network: inline CSS, charts as inline SVG
drawn with matplotlib's SVG backend, no scripts. It is deterministic
(same report, same bytes): no timestamps, SVG ids from a fixed hash salt, no
date in the SVG metadata.

Sections, in the order a timetable planner reads them:

1. headline: line, directions, train types, the conditions assumed, counts
   of flags, totals per direction and train type, and what stands out;
2. margin per interstation along the line, one chart per direction with a
   row per train type: the margin (scheduled − minimum), the margin that
   remains on a bad day (scheduled − degraded minimum), the supplement the
   rule asks for, flagged legs coloured;
3. run curves of one leg (default: the least remaining margin): minimum, as
   scheduled (closed loop), degraded with its low-adhesion stopping pattern,
   and where along the leg the time is lost;
4. stopping time against adhesion for every approach of that train type;
5. the legs in a table, flagged ones first;
6. totals per train (collapsed);
7. route conflicts, when the conflict check gave rows;
8. how the numbers are made.
"""
from __future__ import annotations

import html
import io
import math
from pathlib import Path

import numpy as np

FLAG_COLOURS = {"unassessed": "#37474f", "infeasible": "#c62828", "tight": "#ef8f00", "unreachable": "#6a1b9a",
                "ok": "#2e7d32"}
"""Colour of a leg by its worst flag (also used in the table)."""
MARGIN_COLOUR = "#b0c4de"
"""Bar colour of the nominal margin."""
SVG_SALT = "planner-margins"
"""Fixed ``svg.hashsalt``: matplotlib's SVG ids become deterministic."""

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;margin:0;color:#1d2327;background:#f6f7f9}
main{max-width:1320px;margin:0 auto;padding:18px 28px 60px}
h1{font-size:26px;margin:8px 0 2px}h2{font-size:20px;margin:34px 0 8px;border-bottom:2px solid #d5d9de;padding-bottom:4px}
h3{font-size:16px;margin:18px 0 6px}
p,li{line-height:1.45;font-size:14px}.sub{color:#555;margin:0 0 14px;font-size:14px}
.cards{display:flex;flex-wrap:wrap;gap:12px;margin:14px 0}
.card{background:#fff;border:1px solid #d5d9de;border-radius:8px;padding:10px 16px;min-width:150px}
.card .n{font-size:28px;font-weight:700}.card .l{font-size:13px;color:#555}
.card.bad{border-left:6px solid #c62828}.card.warn{border-left:6px solid #ef8f00}
.card.purple{border-left:6px solid #6a1b9a}.card.ok{border-left:6px solid #2e7d32}.card.info{border-left:6px solid #5a7da8}
.fig{background:#fff;border:1px solid #d5d9de;border-radius:8px;padding:8px;margin:10px 0}
.fig svg{width:100%;height:auto;display:block}
.caption{font-size:13px;color:#444;margin:4px 4px 2px}
.tw{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;background:#fff;font-size:12px;width:100%}
th,td{border:1px solid #dde1e5;padding:3px 5px;text-align:right;white-space:nowrap}
th{background:#eef1f4;position:sticky;top:0;font-weight:600;white-space:normal;vertical-align:bottom}
td.l,th.l{text-align:left}
tr.unassessed td{background:#e3e7ea}
tr.infeasible td{background:#fdecea}tr.tight td{background:#fff4e0}tr.unreachable td{background:#f3e5f5}
tr.sep td{background:#d5d9de;text-align:left;font-weight:600}
.badge{display:inline-block;border-radius:4px;padding:0 5px;margin-right:3px;color:#fff;font-size:11px;font-weight:600}
.b-unassessed{background:#37474f}
.b-infeasible{background:#c62828}.b-tight{background:#ef8f00}.b-unreachable{background:#6a1b9a}
.b-short{background:#fff;color:#8a5a00;border:1px solid #c89b3c}
.neg{color:#c62828;font-weight:600}
details{margin:10px 0}summary{cursor:pointer;font-weight:600;font-size:14px}
.note{background:#fff;border:1px solid #d5d9de;border-radius:8px;padding:8px 16px}
code{font-size:12.5px}
"""


# --- small formatting helpers ------------------------------------------------------

def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _f(x, nd: int = 1, sign: bool = False) -> str:
    """Number for a table cell; '–' for NaN/None."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    return f"{x:+.{nd}f}" if sign else f"{x:.{nd}f}"


def _hms(t: float) -> str:
    if t is None or not math.isfinite(t):
        return "–"
    t = int(round(t))
    return f"{t // 3600:02d}:{t // 60 % 60:02d}:{t % 60:02d}"


def _leg(r) -> str:
    via = f" <span style='color:#777'>(passes {len(r.passes)})</span>" if len(r.passes) else ""
    return f"{_e(r.origin)} → {_e(r.destination)}{via}"


def _flag_of(r) -> str:
    for f in ("unassessed", "infeasible", "unreachable", "tight"):
        if bool(getattr(r, f)):
            return f
    return "ok"


# --- figures ------------------------------------------------------------------------

def _svg(fig) -> str:
    """A matplotlib figure as an inline <svg> element (deterministic)."""
    import matplotlib.pyplot as plt

    buf = io.StringIO()
    fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": "planner"})
    plt.close(fig)
    s = buf.getvalue()
    return s[s.index("<svg"):]


def _mpl():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"svg.hashsalt": SVG_SALT, "svg.fonttype": "none", "font.size": 9,
                         "axes.titlesize": 10, "figure.dpi": 72})
    return plt


def margin_chart(report, direction: str, stations: dict[str, float]) -> str:
    """Bar chart of the margin per leg along the line for one direction (inline SVG).

    One row of axes per train type (legs passing stations in their own row);
    bars span the leg from stop marker to stop marker, running left to right.
    """
    plt = _mpl()
    rows = report.rows[(report.rows.direction == direction) & report.rows.scheduled_running_time_s.notna()]
    if rows.empty:
        return ""
    groups = []
    for t in sorted(rows.train_type.unique()):
        sub = rows[rows.train_type == t]
        plain, passing = sub[sub.passes.map(len) == 0], sub[sub.passes.map(len) > 0]
        if len(plain):
            groups.append((f"{t}: stop to next station", plain))
        if len(passing):
            groups.append((f"{t}: legs passing stations", passing))
    fig, axes = plt.subplots(len(groups), 1, figsize=(13.5, 2.6 * len(groups) + 1.7), sharex=True,
                             squeeze=False)
    lo = min(min(stations.values()), 0.0) / 1000.0
    hi = max(stations.values()) / 1000.0
    ymin = min(0.0, float(np.nanmin(rows.remaining_margin_s))) - 3
    ymax = max(float(np.nanmax(rows.margin_s)), float(np.nanmax(rows.supplement_required_s))) + 4
    for ax, (title, sub) in zip(axes[:, 0], groups):
        # several scheduled times on one leg: draw the one with the least remaining margin
        sub = sub.sort_values("remaining_margin_s", kind="stable").drop_duplicates(["origin", "destination"])
        for r in sub.itertuples(index=False):
            a = stations[r.origin] / 1000.0
            b = stations[r.destination] / 1000.0
            x0, x1 = min(a, b), max(a, b)
            pad = 0.04 * (x1 - x0)
            w = x1 - x0 - 2 * pad
            ax.bar(x0 + pad, r.margin_s, width=w, align="edge", color=MARGIN_COLOUR, edgecolor="#7d93ad", lw=0.6)
            col = FLAG_COLOURS[_flag_of(r)]
            ax.bar(x0 + pad + 0.25 * w, r.remaining_margin_s, width=0.5 * w, align="edge", color=col, alpha=0.9)
            ax.plot([x0 + pad, x0 + pad + w], [r.supplement_required_s] * 2, color="k", lw=1.4)
            y = r.remaining_margin_s
            ax.text(x0 + pad + 0.5 * w, y + (0.6 if y >= 0 else -0.6), f"{y:+.1f}", ha="center",
                    va="bottom" if y >= 0 else "top", fontsize=7.5, fontweight="bold",
                    color="#8e1b1b" if y < 0 else "#1d2327")
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylim(ymin, ymax)
        ax.set_ylabel("seconds")
        ax.set_title(title, loc="left", fontsize=9.5, fontweight="bold", pad=16)
        ax.grid(axis="y", alpha=0.3)
        for sid, x in stations.items():
            ax.axvline(x / 1000.0, color="0.85", lw=0.6, zorder=0)
    order = sorted(stations.items(), key=lambda kv: kv[1])
    for ax in axes[:, 0]:  # station codes above every panel, not only the first
        top = ax.secondary_xaxis("top")
        top.set_xticks([x / 1000.0 for _, x in order], [s for s, _ in order], fontsize=8)
    axes[-1, 0].set_xlabel("chainage [km] (stop markers of this direction)")
    axes[-1, 0].set_xlim(lo - 0.3, hi + 0.3)
    if direction == "up":
        axes[-1, 0].invert_xaxis()  # run left to right
    from matplotlib.patches import Patch
    from matplotlib.lines import Line2D

    handles = [Patch(color=MARGIN_COLOUR, label="margin = scheduled − minimum"),
               Patch(color=FLAG_COLOURS["ok"], label="remaining on a bad day (≥ tight threshold)"),
               Patch(color=FLAG_COLOURS["tight"], label="remaining < tight threshold"),
               Patch(color=FLAG_COLOURS["infeasible"], label="negative: infeasible"),
               Line2D([], [], color="k", lw=1.4, label="supplement the rule asks for")]
    fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=8.5, frameon=False)
    first, last = order[0][0], order[-1][0]
    if direction == "up":
        first, last = last, first
    fig.suptitle(f"{direction}: {first} → {last}, running left to right", x=0.01, y=1 - 0.12 / fig.get_figheight(),
                 ha="left", va="top", fontsize=11, fontweight="bold")
    h = fig.get_figheight()  # fixed margins in inches: tight_layout costs seconds per chart
    fig.subplots_adjust(left=0.06, right=0.99, top=1 - 1.05 / h, bottom=0.95 / h, hspace=0.62)
    return _svg(fig)


def curves_chart(report) -> str:
    """Run curves of the chosen leg and where along it the time goes (inline SVG)."""
    c, k = report.curves, report.chosen
    if not c or not k:
        return ""
    plt = _mpl()
    row = report.rows[(report.rows.direction == k["direction"]) & (report.rows.train_type == k["train_type"])
                      & (report.rows.origin == k["origin"]) & (report.rows.destination == k["destination"])]
    row = row.iloc[0]
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(15.5, 7.4), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    km = c["position_m"] / 1000.0
    ax.step(km, c["vmax_kmh"], where="mid", color="0.55", lw=1.1, label="on-board maximum (limit − margin)")
    ax.plot(km, c["min_speed_kmh"], color="#1f5fa8", lw=1.8,
            label=f"minimum: ratio 100 %, nominal — {row.min_running_time_s:.1f} s")
    if "sched_speed_kmh" in c:
        ax.plot(km, c["sched_speed_kmh"], color="#2e7d32", lw=1.5,
                label=f"as scheduled: on-board logic, departs at ratio {row.ratio_on_time:.0%}\n  "
                      f"{row.scheduled_running_time_s:.0f} s scheduled, arrives {row.arrival_error_s:+.1f} s")
    dkm = c["degraded_position_m"] / 1000.0
    ax.plot(dkm, c["degraded_speed_kmh"], color="#c62828", lw=1.5,
            label=f"bad day: load {report.rule.bad_load:.0%}, traction ×{report.rule.bad_traction:g},\n  "
                  f"ratio 100 % — {row.degraded_min_running_time_s:.1f} s")
    if "pattern_position_m" in c:
        ax.plot(c["pattern_position_m"] / 1000.0, c["pattern_speed_kmh"], color="#c62828", lw=1.5, ls="--",
                label=f"stopping pattern at adhesion {row.adhesion_min_kmh_s:g} km/h/s\n  — {row.stop_time_degraded_s:.1f} s")
    ps = c["pattern_start_m"] / 1000.0
    ax.axvline(ps, color="#c62828", lw=0.8, ls=":")
    ax.text(ps, 3, " pattern start", color="#c62828", fontsize=8, ha="left", va="bottom")
    ax.set_ylabel("speed [km/h]")
    ax.set_ylim(0, float(np.nanmax(c["vmax_kmh"])) * 1.12)
    ax.grid(alpha=0.3)
    # legends beside the axes, never over the curves
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8.2, ncol=1, frameon=False,
              borderaxespad=0.0)
    for x, name in ((km[0], row.origin), (km[-1], row.destination)):
        ax.axvline(x, color="k", lw=1.0)
        ax.text(x, ax.get_ylim()[1] * 0.985, f" {name} ", ha="center", va="top", fontsize=9,
                bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="k", lw=0.6))
    # where the time goes: time behind the minimum run at each point
    tmin = c["min_time_s"]
    if "sched_time_s" in c:
        ax2.plot(km, c["sched_time_s"] - tmin, color="#2e7d32", lw=1.5, label="as scheduled − minimum")
    dt = c["degraded_time_s"] - tmin[: len(c["degraded_time_s"])]
    ax2.plot(dkm, dt, color="#c62828", lw=1.5, label="degraded − minimum")
    if "pattern_position_m" in c:
        x_p = c["pattern_position_m"]
        order = np.argsort(c["position_m"])
        tm_p = np.interp(x_p, c["position_m"][order], tmin[order])
        ax2.plot(x_p / 1000.0, c["pattern_time_s"] - tm_p, color="#c62828", lw=1.5, ls="--")
    ax2.axhline(row.margin_s, color="#1f5fa8", lw=1.0, ls="--")
    ax2.text(km[0], row.margin_s, f"  scheduled margin {row.margin_s:.1f} s", color="#1f5fa8", fontsize=8,
             va="bottom", ha="left")
    ax2.axvline(ps, color="#c62828", lw=0.8, ls=":")
    ax2.set_ylabel("time behind the\nminimum run [s]")
    ax2.set_xlabel("chainage [km]")
    ax2.grid(alpha=0.3)
    ax2.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8.2, frameon=False, borderaxespad=0.0)
    if k["direction"] == "up":
        ax.invert_xaxis()
    fig.suptitle(f"{k['train_type']} {k['direction']} {row.origin} → {row.destination} "
                 f"({row.length_m / 1000:.2f} km): scheduled {row.scheduled_running_time_s:.0f} s, "
                 f"remaining margin on a bad day {row.remaining_margin_s:+.1f} s",
                 x=0.01, ha="left", fontsize=11, fontweight="bold")
    fig.subplots_adjust(left=0.055, right=0.71, top=0.93, bottom=0.08, hspace=0.08)
    return _svg(fig)


def adhesion_chart(report) -> tuple[str, str]:
    """Stopping-pattern time against adhesion for every approach of the chosen leg's train type.

    Returns the SVG and the hardest approach's description.
    """
    k = report.chosen
    sw = report.sweep
    if sw is None or len(sw) == 0 or not k:
        return "", ""
    plt = _mpl()
    tt = k["train_type"]
    rows = report.rows
    plain = rows[(rows.train_type == tt) & (rows.passes.map(len) == 0)][
        ["direction", "origin", "destination"]].drop_duplicates()
    sw = sw.merge(plain, on=["direction", "origin", "destination"])
    sw = sw[sw.train_type == tt]
    fig, axes = plt.subplots(1, 2, figsize=(13.5, 4.4), sharey=True)
    hardest = ""
    worst = (-1.0, None)
    for ax, d in zip(axes, ("down", "up")):
        sub = sw[sw.direction == d]
        losses = []
        for (o, de), g in sub.groupby(["origin", "destination"], sort=True):
            g = g.sort_values("adhesion_kmh_s")
            a = g.adhesion_kmh_s.to_numpy()
            t = g.stop_time_s.to_numpy()
            if not np.isfinite(t[-1]):
                continue
            losses.append((float(np.nanmax(t - t[-1])), o, de, a, t))
        losses.sort(key=lambda x: -x[0])
        for i, (loss, o, de, a, t) in enumerate(losses):
            is_chosen = (d, o, de) == (k["direction"], k["origin"], k["destination"])
            hard = i == 0
            col = "#c62828" if hard else ("#1f5fa8" if is_chosen else "0.7")
            lw = 2.0 if (hard or is_chosen) else 1.0
            ax.plot(a, t - t[-1], color=col, lw=lw, marker="o" if (hard or is_chosen) else None, ms=3,
                    zorder=3 if (hard or is_chosen) else 2)
            if hard or is_chosen:
                # described in a corner (the flat, good-adhesion side), not at the crowded line ends
                ax.text(0.02, 0.95 - 0.07 * (0 if hard else 1), f"{o} → {de}: {t[-1]:.1f} s at {a[-1]:g}, "
                        f"{t[0]:.1f} s at {a[0]:g} km/h/s", transform=ax.transAxes, fontsize=8.5, color=col,
                        va="top", ha="left", fontweight="bold")
            if loss > worst[0]:
                worst = (loss, (d, o, de, t[0], t[-1], a[0], a[-1]))
        ax.set_title(f"{tt} {d}: every approach (grey), hardest (red), the leg above (blue)", fontsize=9.5)
        ax.set_xlabel("adhesion-limited deceleration [km/h/s]")
        ax.grid(alpha=0.3)
        ax.invert_xaxis()  # worse adhesion to the right
    axes[0].set_ylabel("stopping time lost against\nthe best adhesion [s]")
    fig.tight_layout()
    if worst[1] is not None:
        d, o, de, t0, t1, a0, a1 = worst[1]
        hardest = (f"The hardest approach for {tt} is {d} {o} → {de}: the stopping pattern takes {t1:.1f} s "
                   f"at {a1:g} km/h/s and {t0:.1f} s at {a0:g} km/h/s (+{t0 - t1:.1f} s).")
    return _svg(fig), hardest


# --- tables ------------------------------------------------------------------------

def flagged_summary(sched) -> str:
    """The flagged legs on the first screen: what each lacks and where the bad day's time goes."""
    # unassessed legs have their own section, listed first; this one lists the legs judged
    f = sched[(sched.infeasible.fillna(False).astype(bool) | sched.tight.fillna(False).astype(bool)
               | sched.unreachable.fillna(False).astype(bool)) & ~sched.unassessed.astype(bool)]
    if f.empty:
        return "<p><b>No leg is flagged</b>: every timetabled leg keeps its time on a bad day.</p>"
    f = f.sort_values(["remaining_margin_s", "direction", "train_type", "origin"], kind="stable")
    med = float(sched.margin_percent.median())
    out = [f"<h3>Flagged legs ({len(f)} of {len(sched)})</h3><div class='tw'><table><tr><th class='l'>flag</th>"
           "<th class='l'>dir</th><th class='l'>type</th><th class='l'>leg</th><th>trains</th><th>scheduled [s]</th>"
           "<th>margin [s] (%)</th><th>bad-day cost [s]: load + traction + stop</th>"
           "<th>remaining on a bad day [s]</th><th class='l'>why</th></tr>"]
    for r in f.itertuples(index=False):
        flag = _flag_of(r)
        cost = r.degraded_min_running_time_s - r.min_running_time_s
        if flag == "unreachable":
            why = "scheduled longer than the slowest table ratio: the vehicle arrives early"
        else:
            why = (f"margin {r.margin_percent:.1f} % against a median of {med:.1f} %: the timetable grants "
                   f"{r.margin_s:.1f} s where a bad day costs {cost:.1f} s")
        out.append(
            f"<tr class='{flag}'><td class='l'><span class='badge b-{flag}'>{flag}</span></td>"
            f"<td class='l'>{_e(r.direction)}</td><td class='l'>{_e(r.train_type)}</td><td class='l'>{_leg(r)}</td>"
            f"<td>{r.n_trains}</td><td>{_f(r.scheduled_running_time_s, 0)}</td>"
            f"<td>{_f(r.margin_s, 1, True)} ({_f(r.margin_percent, 1)})</td>"
            f"<td>{_f(cost)} = {_f(r.degraded_loss_load_s)} + {_f(r.degraded_loss_traction_s)} + "
            f"{_f(r.degraded_loss_stop_s)}</td><td>{_f(r.remaining_margin_s, 1, True)}</td>"
            f"<td class='l'>{_e(why)}</td></tr>")
    out.append("</table></div>")
    return "\n".join(out)


def bad_day_shares(sched, rule, adh) -> str:
    """Each effect's share of the bad day's cost, summed over every train run of the day."""
    if sched.empty:
        return ""
    w = sched.n_trains.to_numpy(float)
    parts = [("load", "degraded_loss_load_s", rule.bad_day_load,
              f"load {rule.degraded_load:.0%}"),
             ("traction", "degraded_loss_traction_s", rule.bad_day_traction,
              f"traction ×{rule.degraded_traction:g}"),
             ("adhesion (the stop)", "degraded_loss_stop_s", rule.bad_day_adhesion,
              f"adhesion {rule.bad_adhesion_kmh_s(adh):g} km/h/s" if rule.bad_day_adhesion else "stopping brake")]
    vals = [float(np.nansum(sched[c].to_numpy(float) * w)) for _, c, _, _ in parts]
    tot = sum(vals)
    cells = []
    for (name, _c, on, what), v in zip(parts, vals):
        share = f"{100 * v / tot:.0f} %" if tot > 0 else "–"
        state = what if on else "off"
        cells.append(f"<b>{_e(name)}</b> ({_e(state)}): {v / 3600:.2f} h, {share}")
    return ("<p class='sub'>Where a bad day's time goes, summed over every train run of the day: "
            + " · ".join(cells) + ". Each effect is switched on or off and valued in the job file "
            "(<code>[margins]</code> <code>bad_day_*</code>, <code>degraded_*</code>).</p>")


ROW_HEAD = ("<tr><th class='l'>flags</th><th class='l'>dir</th><th class='l'>type</th><th class='l'>leg</th>"
            "<th>trains</th><th>km</th><th>minimum [s]</th><th>min ↑10 s</th><th>scheduled [s]</th>"
            "<th>margin [s] (%)</th><th>rule asks [s]</th><th>bad-day minimum [s]</th>"
            "<th>remaining on a bad day [s]</th><th>bad-day loss: load + traction + stop [s]</th>"
            "<th>ratio at on-time departure</th><th>arrival error nominal / bad day [s]</th>"
            "<th>energy at that ratio vs 100 %</th></tr>")


def _row_html(r) -> str:
    flag = _flag_of(r)
    badges = "".join(f"<span class='badge b-{f}'>{f}</span>"
                     for f in ("unassessed", "infeasible", "tight", "unreachable") if bool(getattr(r, f)))
    if np.isfinite(r.scheduled_running_time_s) and not bool(r.supplement_met):
        badges += "<span class='badge b-short'>supplement short</span>"
    rem = r.remaining_margin_s
    rem_s = _f(rem, 1, sign=True)
    if math.isfinite(rem) and rem < 0:
        rem_s = f"<span class='neg'>{rem_s}</span>"
    tip = r.unassessed_reason if r.unassessed else r.note
    note = f" title='{_e(tip)}'" if tip else ""
    cls = f" class='{flag}'" if flag != "ok" else ""
    return (
        f"<tr{cls}{note}><td class='l'>{badges}</td><td class='l'>{_e(r.direction)}</td>"
        f"<td class='l'>{_e(r.train_type)}</td><td class='l'>{_leg(r)}</td><td>{r.n_trains}</td>"
        f"<td>{r.length_m / 1000:.2f}</td><td>{_f(r.min_running_time_s)}</td>"
        f"<td>{_f(r.min_running_time_rounded_s, 0)}</td><td>{_f(r.scheduled_running_time_s, 0)}</td>"
        f"<td>{_f(r.margin_s, 1, True)} ({_f(r.margin_percent, 1)})</td>"
        f"<td>{_f(r.supplement_required_s)}</td><td>{_f(r.degraded_min_running_time_s)}</td>"
        f"<td>{rem_s}</td><td>{_f(r.degraded_loss_load_s)} + {_f(r.degraded_loss_traction_s)} + "
        f"{_f(r.degraded_loss_stop_s)}</td>"
        f"<td>{'–' if not math.isfinite(r.ratio_on_time) else f'{r.ratio_on_time:.0%}'}</td>"
        f"<td>{_f(r.arrival_error_s, 1, True)} / {_f(r.arrival_error_degraded_s, 1, True)}</td>"
        f"<td>{energy_change(r.energy_saved_percent)}</td></tr>"
    )


def rows_table(rows) -> str:
    """All legs: unassessed ones first (with their reason), then flagged ones (least remaining margin first),
    then the rest in running order."""
    una = rows[rows.unassessed.astype(bool)]
    assessed = rows.drop(una.index)
    flagged = assessed[assessed.infeasible | assessed.tight | assessed.unreachable].sort_values(
        ["remaining_margin_s", "direction", "train_type"], kind="stable")
    rest = assessed.drop(flagged.index)
    out = ["<div class='tw'><table>", ROW_HEAD]
    if len(una):
        out.append(f"<tr class='sep'><td colspan='17'>Unassessed legs ({len(una)}): no bad-day minimum could be "
                   "computed, so infeasible and tight are unknown</td></tr>")
        for r in una.itertuples(index=False):
            out.append(_row_html(r))
            out.append(f"<tr class='unassessed'><td colspan='17' class='l'>↳ {_e(r.unassessed_reason)}</td></tr>")
    out.append(f"<tr class='sep'><td colspan='17'>Flagged legs ({len(flagged)}), least remaining margin first</td></tr>")
    out += [_row_html(r) for r in flagged.itertuples(index=False)]
    out.append(f"<tr class='sep'><td colspan='17'>Other legs ({len(rest)}), in running order</td></tr>")
    out += [_row_html(r) for r in rest.itertuples(index=False)]
    out.append("</table></div>")
    return "\n".join(out)


def totals_table(totals, scopes=("line", "type")) -> str:
    t = totals[totals.level.isin(scopes)].copy()
    t["o"] = t.level.map({"line": 0, "type": 1})
    t = t.sort_values(["direction", "o", "train_type"], kind="stable")
    out = ["<div class='tw'><table><tr><th class='l'>direction</th><th class='l'>train type</th><th>trains</th>"
           "<th>train runs of a leg</th>"
           "<th>sum of minimum running times [s]</th><th>sum of scheduled [s]</th><th>sum of margins [s]</th>"
           "<th>margin %</th><th>sum of bad-day remaining margins [s]</th><th>least remaining, one leg [s]</th>"
           "<th>train runs on an infeasible leg</th><th>… on a tight leg</th><th>… on an unreachable leg</th>"
           "<th>… on a leg short of the rule</th><th>energy saved [kWh]</th></tr>"]
    for r in t.itertuples(index=False):
        bold = " style='font-weight:600'" if r.level == "line" else ""
        out.append(
            f"<tr{bold}><td class='l'>{_e(r.direction)}</td><td class='l'>"
            f"{'all types' if r.level == 'line' else _e(r.train_type)}</td><td>{r.n_trains}</td><td>{r.n_legs}</td>"
            f"<td>{r.min_running_time_s:.0f}</td><td>{r.scheduled_running_time_s:.0f}</td>"
            f"<td>{r.margin_s:.0f}</td><td>{r.margin_percent:.1f}</td><td>{r.remaining_margin_s:+.0f}</td>"
            f"<td>{r.min_remaining_margin_s:+.1f}</td><td>{r.n_infeasible}</td><td>{r.n_tight}</td>"
            f"<td>{r.n_unreachable}</td><td>{r.n_supplement_short}</td><td>{r.energy_saved_kwh:.0f}</td></tr>")
    out.append("</table></div>")
    return "\n".join(out)


def train_table(totals) -> str:
    t = totals[totals.level == "train"].copy()
    t = t.sort_values(["n_infeasible", "min_remaining_margin_s", "train_id"], ascending=[False, True, True],
                      kind="stable")
    out = ["<div class='tw'><table><tr><th class='l'>train</th><th class='l'>dir</th><th class='l'>type</th>"
           "<th class='l'>from → to</th><th>departs</th><th>legs</th><th>minimum [s]</th><th>scheduled [s]</th>"
           "<th>margin [s]</th><th>margin %</th><th>remaining [s]</th><th>worst leg [s]</th>"
           "<th>infeasible</th><th>tight</th><th>unreachable</th></tr>"]
    for r in t.itertuples(index=False):
        cls = " class='infeasible'" if r.n_infeasible else (" class='tight'" if r.n_tight else "")
        out.append(
            f"<tr{cls}><td class='l'>{_e(r.train_id)}</td><td class='l'>{_e(r.direction)}</td>"
            f"<td class='l'>{_e(r.train_type)}</td><td class='l'>{_e(r.origin)} → {_e(r.destination)}</td>"
            f"<td>{_hms(r.first_departure_s)}</td><td>{r.n_legs}</td><td>{r.min_running_time_s:.0f}</td>"
            f"<td>{r.scheduled_running_time_s:.0f}</td><td>{r.margin_s:.0f}</td><td>{r.margin_percent:.1f}</td>"
            f"<td>{r.remaining_margin_s:+.0f}</td><td>{r.min_remaining_margin_s:+.1f}</td>"
            f"<td>{r.n_infeasible}</td><td>{r.n_tight}</td><td>{r.n_unreachable}</td></tr>")
    out.append("</table></div>")
    return "\n".join(out)


def conflicts_section(report) -> str:
    con = report.conflicts
    if con is None:
        return (f"<h2>Route conflicts</h2><p>Not checked: {_e(report.conflicts_note)}.</p>"
                if report.conflicts_note else "")
    if len(con) == 0:
        return "<h2>Route conflicts</h2><p>The conflict check found no overlapping occupation windows.</p>"
    c = con.groupby("conflict_id", sort=True).agg(
        train_a=("train_a", "first"), train_b=("train_b", "first"), rule=("rule", "first"),
        decision=("decision", "first"), delay_s=("delay_s", "first"), overlap_s=("overlap_s", "max"),
        resource=("resource_id", "first"), interlocking=("interlocking", "first"),
        t0=("overlap_start_s", "min"), n=("resource_id", "size"), deadlock=("deadlock", "first"))
    by_rule = ", ".join(f"{v} {_e(k)}" for k, v in c["rule"].value_counts().sort_index().items())
    head = (f"<p>{len(c)} conflicts between {len(c.groupby(['train_a', 'train_b']))} pairs of trains "
            f"({by_rule}); {int(c.deadlock.sum())} would deadlock. The decisions delay the waiting trains by "
            f"{c.delay_s.sum():.0f} s in all, at most {c.delay_s.max():.1f} s. The {min(len(c), 10)} largest delays, in time order; a conflict "
            f"spans one or more consecutive sections or switches.</p>")

    def table(df) -> str:
        out = ["<div class='tw'><table><tr><th>#</th><th>at</th><th class='l'>first</th><th class='l'>waits</th>"
               "<th class='l'>where</th><th class='l'>interlocking</th><th>resources</th><th>overlap [s]</th>"
               "<th>delay [s]</th><th class='l'>rule</th><th class='l'>decision</th></tr>"]
        for cid, r in df.iterrows():
            out.append(f"<tr><td>{cid}</td><td>{_hms(r.t0)}</td><td class='l'>{_e(r.train_a)}</td>"
                       f"<td class='l'>{_e(r.train_b)}</td><td class='l'>{_e(r.resource)}</td>"
                       f"<td class='l'>{_e(r.interlocking)}</td><td>{r.n}</td><td>{r.overlap_s:.1f}</td>"
                       f"<td>{r.delay_s:.1f}</td><td class='l'>{_e(r.rule)}</td><td class='l'>{_e(r.decision)}</td></tr>")
        out.append("</table></div>")
        return "\n".join(out)

    worst = c.sort_values(["delay_s", "t0"], ascending=[False, True], kind="stable").head(10)
    worst = worst.sort_values("t0", kind="stable")  # the largest delays, listed in time order
    return ("<h2>Route conflicts</h2>" + head + table(worst)
            + (f"<details><summary>All {len(c)} conflicts in time order</summary>{table(c.sort_values('t0', kind='stable'))}"
               "</details>" if len(c) > 10 else ""))


# --- the page -------------------------------------------------------------------------

def line_title(name: str, line_id: str) -> str:
    """``name (line_id)``, without repeating the id when the name already ends with it in brackets."""
    name, line_id = str(name).strip(), str(line_id).strip()
    if not name or name == line_id:
        return line_id
    if name.endswith(f"({line_id})"):
        return name
    return f"{name} ({line_id})"


def energy_change(saved_percent: float) -> str:
    """Energy at the on-time ratio against ratio 100 %, in words: ``12 % saved``, ``3 % more``, ``±0 %``.

    Examples
    --------
    >>> energy_change(12.3), energy_change(-4.2), energy_change(-0.2), energy_change(float("nan"))
    ('12 % saved', '4 % more', '±0 %', '–')
    """
    if saved_percent is None or not math.isfinite(saved_percent):
        return "–"
    if abs(saved_percent) < 0.5:
        return "±0 %"
    return f"{saved_percent:.0f} % saved" if saved_percent > 0 else f"{-saved_percent:.0f} % more"


def render_html(report, markers: dict[str, dict[str, float]], datasets_href: str = ".", top: str = "") -> str:
    """The whole report page as one HTML string (module doc for the sections).

    Parameters
    ----------
    report : planner.report.margins.MarginReport
    markers : dict
        ``{direction: {station_id: stop-marker chainage [m]}}`` for the charts
        (:func:`stop_markers`).
    datasets_href : str
        Relative path from the page's folder to the folder holding the ``margins`` and
        ``margin_totals`` datasets (``..`` in a published run, ``.`` for ``planner margins --out``).
    top : str
        An HTML section put first, under the title (the nightly job's "what
        changed since the last run", :func:`planner.report.changes.changes_html`).
    """
    rows = report.rows
    sched = rows[rows.scheduled_running_time_s.notna()]
    n_inf, n_tight, n_unr = int(sched.infeasible.sum()), int(sched.tight.sum()), int(sched.unreachable.sum())
    n_short = int((~sched.supplement_met).sum())
    n_una = int(rows.unassessed.sum())
    trains = report.totals[report.totals.level == "train"]
    rule = report.rule
    adh = report.adhesion_kmh_s
    types = ", ".join(sorted(rows.train_type.unique()))
    dirs = ", ".join(d for d in ("down", "up") if d in set(rows.direction))
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             f"<meta name='viewport' content='width=device-width, initial-scale=1'>"
             f"<title>Margin report — {_e(line_title(report.line_name, report.line_id))}</title>"
             f"<style>{CSS}</style></head><body><main>"]
    parts.append(f"<h1>Running-time margins — {_e(line_title(report.line_name, report.line_id))}</h1>")
    parts.append(
        f"<p class='sub'>Directions {dirs} · train types {types} · {len(sched)} timetabled legs "
        f"(stop to next stop) run by {len(trains)} trains · "
        f"minimum = ratio 100 %, empty, nominal traction · <b>bad day</b> = {_e(rule.describe(adh))} "
        f"(adhesion sweep {adh[0]:g}–{adh[-1]:g} km/h/s) · supplement rule {rule.supplement_percent:g} % + "
        f"{rule.supplement_min_per_100km:g} min/100 km · tight below {rule.tight_threshold_s:g} s remaining</p>")
    if top:
        parts.append(top)
    # cards count distinct legs (train type × stop → next stop × scheduled time); the totals table
    # below counts train runs, and says so
    cards = [
        ("bad" if n_una else "ok", n_una, "legs unassessed: no bad-day minimum could be computed (listed first)"),
        ("bad" if n_inf else "ok", n_inf, "legs infeasible: scheduled below the bad-day minimum"),
        ("warn" if n_tight else "ok", n_tight, f"legs tight: less than {rule.tight_threshold_s:g} s left on a bad day"),
        ("purple" if n_unr else "ok", n_unr, "legs unreachable: longer than the slowest ratio"),
        ("warn" if n_short else "ok", n_short, "legs with a margin below the supplement rule"),
        ("info", f"{len(sched)}", "legs checked (train type × stop → next stop × scheduled time), "
                                  f"run {int(sched.n_trains.sum())} times a day"),
    ]
    parts.append("<div class='cards'>" + "".join(
        f"<div class='card {c}'><div class='n'>{n}</div><div class='l'>{_e(l)}</div></div>" for c, n, l in cards)
        + "</div>")
    # what stands out (among the legs that could be assessed)
    find = []
    if (~sched.unassessed.astype(bool)).any():
        w = sched.sort_values("remaining_margin_s", kind="stable").iloc[0]
        find.append(f"Least margin on a bad day: <b>{_e(w.train_type)} {_e(w.direction)} {_e(w.origin)} → "
                    f"{_e(w.destination)}</b>, scheduled {w.scheduled_running_time_s:.0f} s against a minimum of "
                    f"{w.min_running_time_s:.1f} s and a bad-day minimum of {w.degraded_min_running_time_s:.1f} s "
                    f"({w.remaining_margin_s:+.1f} s).")
        find.append(f"Median margin {sched.margin_s.median():.1f} s ({sched.margin_percent.median():.1f} %); "
                    f"a bad day costs a median {sched.degraded_loss_load_s.median():.1f} s for the load, "
                    f"{sched.degraded_loss_traction_s.median():.1f} s for the weak traction and "
                    f"{sched.degraded_loss_stop_s.median():.1f} s in the stop (low adhesion), so the median "
                    f"remaining margin is {sched.remaining_margin_s.median():+.1f} s.")
        tr = trains[trains.bad_day_shortfall_s > 0]
        if len(tr):
            w = tr.sort_values(["bad_day_shortfall_s", "train_id"], ascending=[False, True], kind="stable").iloc[0]
            find.append(f"{len(tr)} of {len(trains)} trains lose time on a bad day; adding what each leg lacks "
                        f"would lengthen their runs by a median {tr.bad_day_shortfall_s.median():.0f} s "
                        f"(at most {w.bad_day_shortfall_s:.0f} s, train {_e(w.train_id)} {_e(w.origin)} → "
                        f"{_e(w.destination)}).")
        if n_inf:
            short = sched[sched.infeasible]
            find.append(f"{n_inf} of {len(sched)} legs would run late on a bad day even at ratio 100 %, "
                        f"by {(-short.remaining_margin_s).median():.1f} s (median) and "
                        f"{(-short.remaining_margin_s).max():.1f} s at most.")
        e = sched[np.isfinite(sched.energy_saved_kwh)]
        if len(e):
            w_tr = e.energy_saved_kwh * e.n_trains
            tot = (e.energy_at_full_ratio_kwh * e.n_trains).sum()
            verb = "saves" if w_tr.sum() >= 0 else "costs"
            find.append(f"Running at the ratio the margin allows instead of 100 % {verb} "
                        f"{abs(w_tr.sum()):.0f} kWh of traction energy over the day "
                        f"({abs(100 * w_tr.sum() / tot):.1f} %).")
        cl = sched.arrival_error_s.abs()
        find.append(f"The on-board logic (nearest ratio) arrives within {cl.max():.1f} s of the scheduled time "
                    f"on every leg under nominal conditions (median {cl.median():.1f} s); under the bad-day load "
                    f"and traction (stopping brake as planned) it is up to {sched.arrival_error_degraded_s.max():.1f} s late.")
    parts.append("<ul>" + "".join(f"<li>{x}</li>" for x in find) + "</ul>")
    parts.append(flagged_summary(sched))
    parts.append(bad_day_shares(sched, rule, adh))
    parts.append("<h3>Totals per direction and train type (every timetabled train run, the whole day)</h3>")
    parts.append(totals_table(report.totals))

    parts.append("<h2>Margin per interstation along the line</h2>")
    parts.append(
        "<p class='caption'>Each bar spans one leg from stop marker to stop marker. Light bar: margin the timetable "
        "grants over the minimum running time. Narrow coloured bar and its number: what remains on a bad day "
        f"(scheduled − bad-day minimum); below zero the leg is infeasible. Black line: the supplement the rule asks "
        f"for ({rule.supplement_percent:g} % of the minimum + {rule.supplement_min_per_100km:g} min/100 km). "
        "Where a leg has several scheduled times, the one with the least remaining margin is drawn.</p>")
    for d in ("down", "up"):
        if d in markers:
            svg = margin_chart(report, d, markers[d])
            if svg:
                parts.append(f"<div class='fig'>{svg}</div>")

    if report.chosen:
        k = report.chosen
        parts.append(f"<h2>Run curves: {_e(k['train_type'])} {_e(k['direction'])} {_e(k['origin'])} → "
                     f"{_e(k['destination'])}</h2>")
        parts.append(
            "<p class='caption'>The leg with the least remaining margin (or the one asked for with "
            "<code>--curves</code>). Top: speed against chainage for the minimum run, the run the on-board logic "
            "makes for the scheduled time (it re-chooses the ratio at every evaluation point), and the bad-day "
            "run, which hands over to the stopping pattern at the pattern start. Bottom: how far each run is "
            "behind the minimum run at each point; the dashed blue line is the margin the timetable grants, so "
            "a red curve that ends above it cannot be kept.</p>")
        parts.append(f"<div class='fig'>{curves_chart(report)}</div>")
        svg, hardest = adhesion_chart(report)
        if svg:
            parts.append("<h2>Stopping time against adhesion</h2>")
            parts.append(
                f"<p class='caption'>Minimum-time jerk-limited stopping pattern from the pattern start at the "
                f"speed of the minimum run, for every adhesion level of the sweep, relative to the best level. "
                f"Worse adhesion to the right; where a curve is flat the comfort limit, not adhesion, bounds the "
                f"braking. {_e(hardest)}</p>")
            parts.append(f"<div class='fig'>{svg}</div>")

    parts.append("<h2>Every leg</h2>")
    parts.append(
        "<p class='caption'>One row per leg and scheduled time (trains with the same leg and time share a row). "
        "<i>min ↑10 s</i>: the minimum rounded up to the 10-second timetable unit. <i>bad-day loss</i>: what the "
        "degraded load and traction cost up to the pattern start, and what the low-adhesion stop costs against "
        "the planned stopping brake. <i>ratio</i>: the target-speed ratio the vehicle picks at an on-time "
        "departure. <i>arrival error</i>: closed loop of the on-board logic, positive = late. <i>energy saved</i>: "
        "traction energy at that ratio against ratio 100 %. Hover a row for notes.</p>")
    parts.append(rows_table(rows))
    parts.append(f"<details><summary>Totals per train ({len(trains)} trains; with infeasible legs first)</summary>"
                 f"{train_table(report.totals)}</details>")
    parts.append(conflicts_section(report))
    parts.append(
        "<h2>How the numbers are made</h2><div class='note'><ul>"
        "<li><b>Minimum</b>: table (a) at ratio 100 % — full notch to the on-board maximum, constant-speed "
        "hold, service-brake curves to lower limits and the stopping brake to the marker; empty train, nominal "
        "traction (the conditions of the running-time tables).</li>"
        f"<li><b>Bad-day minimum</b>: the same run at load {rule.bad_load:.0%} and traction "
        f"×{rule.bad_traction:g} up to the pattern start (TASC beacon, else {report.approach_m:g} m before the "
        f"marker; moved back where the lowest adhesion needs more room), then "
        + (f"the minimum-time jerk-limited stopping pattern at {rule.bad_adhesion_kmh_s(adh):g} km/h/s adhesion "
           "(deceleration limit min(comfort, adhesion) plus the gradient's part, the on-board maximum as speed "
           "limit, the vehicle's jerk limit)." if rule.bad_day_adhesion else
           "the stopping brake of the running-time tables (the adhesion effect is off in the job file).")
        + " Each effect (load, traction, adhesion) is switched and valued in the job file's <code>[margins]</code>; "
        "its share is the load alone against the nominal run, then the traction on top of it, then the stop.</li>"
        "<li><b>Flags</b>: <i>unassessed</i> — the bad-day minimum could not be computed (the row says why, e.g. "
        "no stopping pattern at the lowest adhesion); its infeasible and tight are unknown (null in the dataset); "
        "<i>infeasible</i> — scheduled below the bad-day minimum; <i>tight</i> — not infeasible "
        f"but less than {rule.tight_threshold_s:g} s left; <i>unreachable</i> — scheduled above the slowest table "
        "time (lowest ratio), so the vehicle would arrive early. <i>supplement short</i> — the margin is below the "
        "rule (not a flag).</li>"
        "<li><b>Ratio and arrival error</b>: the on-board nearest rule on table (a) with designated time = "
        "scheduled; the closed loop re-chooses at every evaluation point from table (b).</li>"
        f"<li>The datasets <a href='{_e(datasets_href)}/margins/'><code>margins</code></a> and "
        f"<a href='{_e(datasets_href)}/margin_totals/'><code>margin_totals</code></a> "
        f"({'in this folder' if datasets_href == '.' else 'in the run folder, one level up from this page'}) "
        "hold every number with its unit in the column name.</li></ul></div>")
    parts.append("</main></body></html>\n")
    return "\n".join(parts)


def stop_markers(line) -> dict[str, dict[str, float]]:
    """``{direction: {station_id: stop-marker chainage [m]}}`` of a line."""
    return {d: {s.station_id: s.stop_m(d) for s in line.stations} for d in ("down", "up")}


def write_html(report, line, path: str | Path, datasets_root: str | Path | None = None, top: str = "") -> Path:
    """Write the page to ``path`` atomically (temp file in the same folder, then rename).

    ``datasets_root``: the folder holding the ``margins`` datasets (default: the page's folder);
    the page links to it by a relative path. ``top`` as in :func:`render_html`.
    """
    import os

    from planner.io.atomic import write_bytes_atomic

    path = Path(path)
    href = "." if datasets_root is None else Path(os.path.relpath(Path(datasets_root), path.parent)).as_posix()
    write_bytes_atomic(path, render_html(report, stop_markers(line), datasets_href=href, top=top).encode("utf-8"))
    return path
