"""The run overview page ``outputs/<run>/index.html``: where everything of a run is, on one self-contained page.

Sections, in the order someone opening a run reads them:

1. the run: id, job, inputs digest, code digest, software versions; the
   operating day it plans (what is in force, what the restrictions do to the
   flags, what changed since the previous day), and what changed since the
   previous run (counts per line, linked to the section at the top of each
   margin report);
2. flags (impossible, short on a bad day, tight, unreachable, inaccurate and
   unassessed legs, stalls, infeasible stops, conflicts) and the notes of the run;
3. pages: the restrictions in force (a line with a daily feed), the margin report and the train graph of
   each line;
4. inputs: each line database with its source digest and, per table of the
   copy kept under ``inputs/<line_id>/``, rows and SHA-256; the job
   parameters;
5. steps: time, units computed and units reused;
6. datasets: every dataset with its row count, its partitions and a link to
   its schema (declared columns, types and meanings, further down the page);
7. bundles: every bundle with its verify status
   (:func:`planner.bundle.container.verify_bundle` against the run's public key), size,
   SHA-256 and tables.

Everything is inline (CSS, no script, no image, no network); links are
relative, so the run folder can be moved or copied whole. The page depends
only on the run folder, so the same run gives the same bytes.
"""
from __future__ import annotations

import hashlib
import html
import json
from pathlib import Path
from typing import Any, Sequence

from planner.report.leg_flags import FLAGS, FLAGS_SHOWN

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;margin:0;color:#1d2327;background:#f6f7f9}
main{max-width:1200px;margin:0 auto;padding:16px 26px 60px}
h1{font-size:24px;margin:6px 0 2px}h2{font-size:18px;margin:28px 0 8px;border-bottom:2px solid #d5d9de;padding-bottom:3px}
h3{font-size:15px;margin:14px 0 4px}p,li{font-size:14px;line-height:1.45}.sub{color:#555;font-size:13px;margin:0 0 10px}
.cards{display:flex;flex-wrap:wrap;gap:10px;margin:10px 0}
.card{background:#fff;border:1px solid #d5d9de;border-radius:8px;padding:8px 14px;min-width:130px;color:inherit;
text-decoration:none}a.card:hover{box-shadow:0 1px 4px rgba(0,0,0,.25)}
.card .n{font-size:24px;font-weight:700}.card .l{font-size:12px;color:#555}
.card.bad{border-left:6px solid #c62828}.card.warn{border-left:6px solid #ef8f00}.card.ok{border-left:6px solid #2e7d32}
.card.info{border-left:6px solid #5a7da8}
p.warn{border-left:6px solid #ef8f00;background:#fff;padding:6px 10px}
table{border-collapse:collapse;background:#fff;font-size:12.5px;margin:4px 0 10px}
th,td{border:1px solid #dde1e5;padding:3px 7px;text-align:left;vertical-align:top}
th{background:#eef1f4;font-weight:600}td.n{text-align:right;font-variant-numeric:tabular-nums}
code{font-size:12px}.ok{color:#2e7d32;font-weight:600}.bad{color:#c62828;font-weight:600}.dev{color:#b26a00;font-weight:600}
a{color:#1f5fa8}details{margin:6px 0}summary{cursor:pointer;font-weight:600;font-size:14px}
.links a{display:inline-block;margin:2px 12px 2px 0;font-size:14px}
p.date{font-size:15px;margin:2px 0 6px}
"""


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _table(head: Sequence[str], rows: Sequence[Sequence[str]], num: Sequence[int] = ()) -> str:
    h = "".join(f"<th>{_e(x)}</th>" for x in head)
    body = "".join("<tr>" + "".join(f"<td class='n'>{c}</td>" if i in num else f"<td>{c}</td>" for i, c in enumerate(r))
                   + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def _bundles(run_dir: Path, at_s: int | None = None) -> list[list[str]]:
    """Each bundle verified as a vehicle would, at ``at_s`` (the start of the run's operating day: bundles
    for a day are loaded for that day, so a run for a later day must not read as refused; None: now)."""
    folder = run_dir / "bundles"
    pub = folder / "signing_key.pub.pem"
    return [bundle_row(b, pub, at_s) for b in (sorted(folder.glob("*.pdb")) if folder.is_dir() else [])]


def bundle_row(b: Path, pub: Path, at_s: int | None = None) -> list[str]:
    """The bundles section's row of the bundle file ``b``: verified as a vehicle would, at ``at_s``, with the
    public key ``pub`` (:func:`_bundles`; the nightly job verifies each bundle on the worker that built it,
    once it is written)."""
    from planner.bundle.verify import verify_bundle
    from planner.errors import PlannerError
    from planner.io.memory import give_back

    b = Path(b)
    give_back()  # what verifying the one before left free: on the 10x line 85-210 MB a bundle, which added up
    try:
        # a development-signed bundle verifies in full (signature, hashes, schema); it says so instead of
        # failing: vehicles refuse it, and `planner bundle verify` without --allow-dev does too
        info = verify_bundle(b, pub, allow_dev=True, at=at_s)
        status = ("<span class='ok'>verified</span>" if info.key_kind == "production" else
                  "<span class='dev'>verified, development key</span>: not for service (vehicles refuse it)")
        status += "" if info.complete else f" (partial: {_e(info.incomplete_text())})"
        tables = ", ".join(f"{f.name.removesuffix('.parquet')} {f.rows}" for f in info.files)
        return [f"<code>{_e(b.name)}</code>", status, f"{info.size_bytes:,}", f"<code>{info.sha256[:16]}</code>",
                f"{_e(info.line_id)} {_e(info.direction)} {_e(info.train_type)}", _e(tables)]
    except PlannerError as e:  # named by the bundle's file name, not this machine's paths
        why = str(e).replace(str(b), b.name)
        return [f"<code>{_e(b.name)}</code>", f"<span class='bad'>FAILED</span>: {_e(why)}", f"{b.stat().st_size:,}",
                f"<code>{_sha(b)[:16]}</code>", "", ""]


def _inputs(run_dir: Path, manifest: dict[str, Any]) -> list[str]:
    """The inputs section: each line's source, digest and table copy, and the job parameters."""
    from planner.report.published_run import INPUTS_DIR

    parts = []
    parts.append("<h2 id='inputs'>Inputs</h2>")
    for rec in manifest.get("lines", []):
        lid = rec["line_id"]
        folder = run_dir / INPUTS_DIR / lid
        parts.append(f"<h3>Line {_e(lid)}</h3><p class='sub'>from <code>{_e(rec.get('path', ''))}</code> · source digest "
                     f"<code>{_e(rec.get('source_digest', ''))}</code>"
                     + (f" · a copy of its tables is in <a href='{INPUTS_DIR}/{_e(lid)}/'><code>{INPUTS_DIR}/{_e(lid)}/</code></a>"
                        if folder.is_dir() else "") + "</p>")
        if folder.is_dir():
            import pyarrow.parquet as pq

            rows = [[f"<code>{_e(f.name)}</code>", f"{pq.ParquetFile(f).metadata.num_rows:,}", f"{f.stat().st_size:,}",
                     f"<code>{_sha(f)}</code>"] for f in sorted(folder.glob("*.parquet"))]
            parts.append(_table(["table", "rows", "bytes", "SHA-256"], rows, num=(1, 2)))
    params = manifest.get("parameters", {})
    prow = []
    for sec in sorted(params):
        val = params[sec]
        if isinstance(val, dict):
            prow += [[f"<code>[{_e(sec)}] {_e(k)}</code>", f"<code>{_e(json.dumps(v, ensure_ascii=False))}</code>"]
                     for k, v in sorted(val.items())]
        else:
            prow.append([f"<code>{_e(sec)}</code>", f"<code>{_e(json.dumps(val, ensure_ascii=False))}</code>"])
    parts.append("<details><summary>Job parameters (" + str(len(prow)) + ")</summary>" + _table(["key", "value"], prow)
                 + "</details>")
    return parts


def _kernels(sw: dict) -> str:
    """", numba 0.x (kernels built at install)" or which ran just in time; empty for older manifests."""
    k = sw.get("kernels") or {}
    if not k:
        return ""
    how = ("kernels built at install" if set(k.values()) == {"aot"} else
           "kernels " + ", ".join(f"{n} {'built at install' if b == 'aot' else 'compiled just in time'}"
                                  for n, b in sorted(k.items())))
    return f", numba {_e(sw.get('numba', '?'))} ({_e(how)})"


def _dates(manifest: dict[str, Any]) -> str:
    """The run's operating day (what it plans) and run date (its datasets' run_date= folder), as a line."""
    from planner.pages.run_head import day_words

    day = day_words(manifest.get("operating_day"))
    words = [f"<b>{_e(day[0].upper() + day[1:])}</b>" if day else ""]
    if manifest.get("run_date"):
        words.append(f"run date {_e(manifest['run_date'])} (every dataset's run_date= folder)")
    words = [w for w in words if w]
    return f"<p class='date'>{' · '.join(words)}</p>" if words else ""


def bundle_rows(run_dir: str | Path, manifest: dict[str, Any]) -> list[list[str]]:
    """The bundles section's rows: each bundle of the run folder verified (:func:`_bundles`) at the start of
    the manifest's operating day."""
    return _bundles(Path(run_dir), (manifest.get("operating_day") or {}).get("start_utc_s"))


def _over(manifest: dict[str, Any]) -> str:
    """A banner when the run plans an operating day that ended before it was built (its bundles are then for a day
    that is over: every vehicle refuses them)."""
    from planner.bundle.manifest import parse_time
    from planner.line.operating_day import day_over

    built = (manifest.get("bundles_release") or {}).get("built_at")
    try:
        text = day_over(manifest.get("operating_day") or {}, parse_time(built, "built_at")) if built else ""
    except Exception:  # noqa: BLE001 - a manifest from before these keys: nothing to say
        return ""
    return f"<p class='warn'><b>Day already over:</b> {_e(text)}.</p>" if text else ""


def _day_as_it_runs(rob: dict) -> list[str]:
    """One line per line: the predicted day and the simulated days' punctuality, linked to its page."""
    out = []
    for lid, r in sorted(rob.items()):
        sim = (f"; over {r['days']} simulated days {r['within_180s']:.1%} of arrivals within 3 min, "
               f"{r['within_60s']:.1%} within 1 min" if r.get("days") else "; no days simulated")
        out.append(f"<p class='links'><b>{_e(lid)}</b>, the day as it will run: {r['late_trains']} trains late on the "
                   f"predicted day (largest delay {r['max_delay_s']:.0f} s), {r['knock_on_conflicts']} knock-on "
                   f"conflicts (beyond the timetable's own){_e(sim)} — <a href='report/{_e(lid)}_robustness.html'>punctuality page</a></p>")
    return ["<h2 id='day-as-it-runs'>The day as it will run</h2>" + "".join(out)] if out else []


def render_overview(run_dir: str | Path, manifest: dict[str, Any], *, notes: Sequence[str] = (),
                    bundles: list[list[str]] | None = None) -> str:
    """The overview page of a run folder as HTML (module doc for the sections); ``bundles``: the bundles
    section's rows when verified beforehand (:func:`bundle_rows`; the nightly job verifies each bundle where it
    was built, :func:`bundle_row`)."""
    from planner.report.catalog import datasets

    run_dir = Path(run_dir)
    run_id = manifest.get("run_id", run_dir.name)
    sw = manifest.get("software", {})
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>Run {_e(run_id)} — planner</title><style>{CSS}</style></head><body><main>",
        f"<h1>Run <code>{_e(run_id)}</code> <span style='color:#777;font-weight:400'>job {_e(manifest.get('job', ''))}</span></h1>",
        _dates(manifest),
        _over(manifest),
        f"<p class='sub'>inputs digest <code>{_e(manifest.get('inputs_digest', ''))}</code> · code digest "
        f"<code>{_e(str(manifest.get('code_digest', ''))[:16])}</code> · planner {_e(sw.get('planner', '?'))}, "
        f"Python {_e(sw.get('python', '?'))}, numpy {_e(sw.get('numpy', '?'))}, pyarrow {_e(sw.get('pyarrow', '?'))}"
        + _kernels(sw) + "</p>",
    ]
    # the operating day, for someone who has never seen one (planner.pages.day_changes)
    from planner.pages.day_changes import overview_html

    parts.append(overview_html(manifest.get("operating_day")))
    # flags
    flags = manifest.get("flags", {})
    labels = {f.name: f.card for f in FLAGS_SHOWN} | {
              "infeasible": "legs infeasible (below the bad-day minimum; a run from before impossible and short "
                            "on a bad day were told apart)",
              "infeasible_stops": "stopping patterns infeasible (approach × adhesion)",
              "conflicts": "route conflicts",
              "stalls": "legs where a train stalls under some scenario (each leg once, with or without the day's "
                        "restrictions; the notes say where)",
              "no_stop": "legs where no stopping pattern stops the train (each leg once, with or without the day's "
                         "restrictions; the notes say where)",
              "unrouted": "trains the track network cannot carry, left out of the conflict check (the notes say "
                          "why)"}
    severity = {f.name: f.severity for f in FLAGS_SHOWN} | {"conflicts": "bad", "stalls": "bad", "no_stop": "bad",
                                                           "infeasible": "bad", "unrouted": "bad"}
    # the margin report's flags first, in their order (worst first), then the others by name
    order = [f for f in FLAGS if f in flags] + sorted(k for k in flags if k not in FLAGS)
    cards = [(severity.get(k, "warn") if flags[k] else "ok", flags[k], labels.get(k, k)) for k in order]
    unchecked = {"no track network": "no track network (nodes.parquet, edges.parquet)",
                 "disabled": "[conflicts] enabled = false"}
    cards += [("warn", "–", f"conflicts not checked: {unchecked[x['conflicts']]} ({x['line_id']})")
              for x in manifest.get("lines", []) if x.get("conflicts") in unchecked]
    # each card opens where its legs are listed: the margin report's flagged legs or conflicts (a run of one line),
    # the pages of the lines (several), the notes of the run (stalls, stops: the notes say where)
    from planner.report.published_run import path_id

    lids = [x["line_id"] for x in manifest.get("lines", [])]
    report = f"report/{path_id(lids[0])}_margins.html" if len(lids) == 1 else None
    where = {"conflicts": f"{report}#conflicts" if report else "#pages", "infeasible_stops": "#notes",
             "stalls": "#notes", "no_stop": "#notes", "unrouted": "#notes"}
    hrefs = [where.get(k, f"{report}#flagged" if report else "#pages") for k in order]
    hrefs += ["#inputs"] * (len(cards) - len(hrefs))
    parts.append("<h2 id='flags'>Flags</h2><div class='cards'>" + "".join(
        f"<a class='card {c}' href='{_e(h)}'><div class='n'>{n}</div><div class='l'>{_e(l)}</div></a>"
        for (c, n, l), h in zip(cards, hrefs)) + "</div>")
    parts += _day_as_it_runs(manifest.get("robustness") or {})
    if notes:
        parts.append("<details id='notes'><summary>Notes of the run (" + str(len(notes)) + ")</summary><ul>"
                     + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul></details>")
    # changes
    ch = manifest.get("changes") or {}
    lines = [x["line_id"] for x in manifest.get("lines", [])]
    parts.append("<h2 id='changes'>What changed since the last run</h2>")
    if not ch.get("base_run"):
        parts.append("<p>First run in this output folder: nothing to compare with.</p>")
    elif ch.get("status") == "failed":
        parts.append(f"<p class='warn'>Comparing with run <code>{_e(ch['base_run'])}</code> failed, so this run lists "
                     f"no changes (its own outputs are complete and published): {_e(ch.get('error', ''))}</p>")
    else:
        rows = []
        for lid in lines:
            c = ch.get("lines", {}).get(lid)
            if c is None:
                rows.append([_e(lid), "not compared", ""])
                continue
            what = ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in c.items() if v) or "nothing"
            rows.append([_e(lid), _e(what), f"<a href='report/{_e(lid)}_margins.html#changes'>details</a>"])
        parts.append(f"<p>Compared with run <code>{_e(ch['base_run'])}</code>; every change is a row of the "
                     "<a href='#ds-changes'><code>changes</code></a> dataset.</p>" + _table(["line", "changes", ""], rows))
    # pages
    parts.append("<h2 id='pages'>Pages</h2>")
    for lid in lines:
        links = []
        for rel, label in ((f"report/{lid}_restrictions.html", "restrictions in force"),
                           (f"report/{lid}_margins.html", "margin report"),
                           (f"report/{lid}_robustness.html", "the day as it will run (punctuality)"),
                           (f"graph/{lid}_graph.html", "train graph"),
                           (f"timetable/{lid}_timetable.html", "running-time tables")):
            if (run_dir / rel).is_file():
                links.append(f"<a href='{_e(rel)}'>{_e(label)}</a>")
        parts.append(f"<p class='links'><b>{_e(lid)}</b>: " + ("".join(links) or "none") + "</p>")
    parts += _inputs(run_dir, manifest)
    # steps
    tim, comp, reu = manifest.get("timings_s", {}), manifest.get("units_computed", {}), manifest.get("units_reused", {})
    steps = list(tim) + [s for s in list(comp) + list(reu) if s not in tim]
    srows = []
    for s in steps:
        c, r = comp.get(s), reu.get(s)
        what = ("—" if c is None and r is None else "recomputed" if not r else "reused" if not c else "partly reused")
        srows.append([_e(s), f"{tim[s]:.1f}" if s in tim else "", "" if c is None else str(c), "" if r is None else str(r),
                      what])
    parts.append("<h2 id='steps'>Steps</h2>" + _table(["step", "time [s]", "units computed", "units reused", ""], srows,
                                                       num=(1, 2, 3))
                 + "<p class='sub'>A unit is reused when its key (digest of exactly the inputs it depends on) is in "
                 "the work cache; the publish step runs after this page is written. Some steps run beside others "
                 "(the conflicts and the train graph's trajectories beside the closed loop, the bundles beside the "
                 "margins, the speed–distance charts beside the pages), so the times add up to more than the run took.</p>")
    # datasets
    docs = {d.name: d for d in datasets()}
    counts = manifest.get("rows", {})
    drows = []
    for name, d in docs.items():
        present = (run_dir / name).is_dir()
        drows.append([f"<a href='#ds-{_e(name)}'><code>{_e(name)}</code></a>",  # its columns, not a folder listing
                      f"{counts[name]:,}" if name in counts else ("0" if present else "not written"),
                      _e(d.step), _e(", ".join(d.partitions)),
                      f"<code>{_e(name)}/</code>" if present else ""])
    parts.append("<h2 id='datasets'>Datasets</h2>" + _table(["dataset (its columns)", "rows", "step", "partitioned by",
                                                             "folder"], drows, num=(1,))
                 + "<p class='sub'>Hive-partitioned Parquet; <code>README.md</code> in this folder shows how to read "
                 "them with pandas, pyarrow and DuckDB.</p>")
    # bundles
    day = manifest.get("operating_day") or {}
    brows = bundle_rows(run_dir, manifest) if bundles is None else bundles
    parts.append("<h2 id='bundles'>Bundles</h2>" + (_table(["bundle", "verify", "bytes", "SHA-256", "for", "tables (rows)"],
                                                           brows, num=(2,)) if brows else "<p>none</p>")
                 + "<p class='sub'>Verified with <code>bundles/signing_key.pub.pem</code> of this run, as "
                 "<code>planner bundle verify --allow-dev</code> does: signature, hashes, schema and consistency; a "
                 "development key is named, since vehicles in service refuse it"
                 + (f"; checked at the start of operating day {_e(day['day'])} ({_e(day.get('start', ''))}), when "
                    "vehicles load them" if day.get("day") else "") + ".</p>")
    # schemas
    parts.append("<h2 id='schemas'>Dataset schemas</h2>")
    for name, d in docs.items():
        meta = d.schema.metadata or {}
        desc = meta.get(b"description", b"").decode()
        rows = [[f"<code>{_e(f.name)}</code>", _e(f.type), _e((f.metadata or {}).get(b"description", b"").decode())]
                for f in d.schema]
        parts.append(f"<details id='ds-{_e(name)}'><summary><code>{_e(name)}</code> — {_e(desc)}</summary>"
                     + _table(["column", "type", "meaning"], rows) + "</details>")
    parts.append("</main></body></html>\n")
    return "\n".join(parts)


def write_overview(run_dir: str | Path, manifest: dict[str, Any] | None = None, *, notes: Sequence[str] = (),
                   bundles: list[list[str]] | None = None) -> Path:
    """Write ``index.html`` into a run folder atomically (the manifest read from the folder when not given)."""
    from planner.io.atomic import write_bytes_atomic

    run_dir = Path(run_dir)
    if manifest is None:
        from planner.report.published_run import read_manifest

        manifest = read_manifest(run_dir)
    path = run_dir / "index.html"
    write_bytes_atomic(path, render_overview(run_dir, manifest, notes=notes, bundles=bundles).encode("utf-8"))
    return path
