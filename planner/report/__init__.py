"""What people read: the margin computation (``margin_rule``, ``leg_margin``,
``margins``, ``margin_datasets``: running-time supplements, bad-day costs), the
HTML margin report (``html``), the train graph, the run overview, changes since
the last run, the evaluation-interval study, the catalogue of published datasets
(``catalog``) and every chart (``plots``).

Takes a ``Line`` and the published datasets; gives datasets, pages and images.
"""
