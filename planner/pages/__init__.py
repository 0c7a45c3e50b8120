"""The pages a person opens, above the computations they show.

Each module writes one kind of self-contained HTML page (no network) of a published run:
``overview`` (the run's ``index.html``), ``margin_report`` with its chart sections
(``margin_charts``; every chart of these pages is SVG written by ``svg_plot``, no matplotlib) and the "what changed" section (``changes``), ``train_graph`` (the
interactive time-distance diagram), ``timetable`` (the running-time table per train),
``speed_chart`` (a speed-distance chart per leg) and ``restrictions`` (the restrictions in force
on the operating day). The numbers come from ``planner.report`` (margins, train graph data,
changes, the per-train timetable) and the datasets; nothing here computes what a dataset holds.
"""
