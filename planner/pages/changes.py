"""The "what changed since the last run" section of the margin report (an HTML fragment with its own CSS).

Takes the :class:`planner.report.changes.LineChanges` of a line (or None for a
first run); gives the section the nightly job puts at the top of the margin
report and ``planner diff --out`` writes: the input changes (line tables, job parameters, the
operating days' restrictions and trains) with the legs each one moved, legs that moved for no input
change, flags, conflicts, bundles.
"""
from __future__ import annotations

import html

from planner.line.units import shown
from planner.report.changes import INPUTS, LineChanges, _num

CSS = """
.changes{background:#fff;border:1px solid #d5d9de;border-left:6px solid #5a7da8;border-radius:8px;padding:8px 16px;margin:12px 0}
.changes h2{margin:4px 0 6px;border:0;font-size:18px}.changes h3{margin:10px 0 4px;font-size:14px}
.changes ul{margin:2px 0 6px;padding-left:20px}.changes li{font-size:13px;line-height:1.4}
.changes .up{color:#c62828;font-weight:600}.changes .down{color:#2e7d32;font-weight:600}
.changes table{width:auto;margin:4px 0}
"""


def changes_html(ch: LineChanges | None, *, first_run_note: str = "",
                 title: str = "What changed since the last run") -> str:
    """The "what changed since the last run" section (self-contained HTML fragment with its own CSS)."""
    e = lambda x: html.escape(str(x), quote=True)  # noqa: E731
    if ch is None:
        return (f"<style>{CSS}</style><section class='changes' id='changes'><h2>{e(title)}</h2>"
                f"<p>{e(first_run_note or 'No earlier run to compare with.')}</p></section>")
    head = (f"<style>{CSS}</style><section class='changes' id='changes'><h2>{e(title)}</h2>"
            f"<p class='sub'>Run <code>{e(ch.run)}</code> compared with <code>{e(ch.base_run)}</code>; legs listed when "
            f"their minimum or margin moved by more than {ch.threshold_s:g} s. Dataset <code>changes</code> holds every row.</p>")
    if not ch.rows:
        return head + "<p>Nothing changed in the inputs or the outputs.</p>" + "".join(
            f"<p>{e(n)}</p>" for n in ch.notes) + "</section>"
    parts = [head]
    inputs = ch.of(*INPUTS)
    legs = ch.of("leg")
    parts.append("<h3>Inputs</h3><ul>" + ("".join(f"<li>{e(r['detail'])}" + _effect(r, legs, e) + "</li>"
                                                    for r in inputs) or "<li>none</li>") + "</ul>")
    explained = {r["change_id"] for r in legs if r["caused_by"]}
    other = [r for r in legs if r["change_id"] not in explained]
    if other:
        groups: dict[str, list] = {}
        for x in other:
            groups.setdefault(x["subject"], []).append(x)
        items = [f"<li>{_leg_group(k, v, e)}</li>" for k, v in groups.items()]
        parts.append("<h3>Legs that moved without an input change reaching them</h3><ul>" + "".join(items[:60])
                     + (f"<li>… {len(items) - 60} more</li>" if len(items) > 60 else "") + "</ul>")
    for cat, title in (("flag", "Flags that appeared or cleared"), ("conflict", "Conflicts that appeared or cleared"),
                       ("bundle", "Bundles whose content changed")):
        rows = ch.of(cat)
        if rows:
            parts.append(f"<h3>{title}</h3><ul>" + "".join(f"<li>{e(r['detail'])}</li>" for r in rows[:60])
                         + (f"<li>… {len(rows) - 60} more</li>" if len(rows) > 60 else "") + "</ul>")
    parts += [f"<p>{e(n)}</p>" for n in ch.notes]
    return "".join(parts) + "</section>"


MEASURE_WORDS = {"min_running_time_s": "minimum", "margin_s": "margin", "remaining_margin_s": "bad-day margin"}


def _leg_group(subject: str, rows, e) -> str:
    """One leg, every measure that moved: ``minimum 125.3 → 151.1 s (+25.8 s), margin …``."""
    bits = []
    for x in rows:
        if x["field"] in MEASURE_WORDS and x["delta"] is not None:
            worse = (x["delta"] > 0) == (x["field"] == "min_running_time_s")
            bits.append(f"{MEASURE_WORDS[x['field']]} {shown(_num(x['before']))} → {shown(_num(x['after']))} s "
                        f"<span class='{'up' if worse else 'down'}'>({x['delta']:+.1f} s)</span>")
        else:  # "leg <subject> appeared": the subject is the item's own head already
            d = x["detail"]
            bits.append(e(d[len(f"leg {subject}"):].lstrip(": ") if d.startswith(f"leg {subject}") else d))
    return f"<b>{e(subject)}</b>: " + ", ".join(bits)


def _effect(r, legs, e) -> str:
    hit = [x for x in legs if r["change_id"] in x["caused_by"]]
    if not hit:
        return (" — <i>no leg moved by more than the threshold</i>"
                if r["category"] in ("line_table", "restriction") else "")
    groups: dict[str, list] = {}
    for x in hit:
        groups.setdefault(x["subject"], []).append(x)
    items = [f"<li>{_leg_group(k, v, e)}</li>" for k, v in groups.items()]
    return (f" — affects {len(groups)} leg{'s' if len(groups) != 1 else ''}:<ul>" + "".join(items[:40])
            + (f"<li>… {len(items) - 40} more</li>" if len(items) > 40 else "") + "</ul>")
