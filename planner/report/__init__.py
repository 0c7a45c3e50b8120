"""What people read: the margin computation (running-time supplements, bad-day
costs), the HTML margin report, the train graph, the run overview, changes
since the last run, the evaluation-interval study, and every chart
(``plots``).

Takes a ``Line`` and the published datasets; gives datasets, pages and images.
"""
