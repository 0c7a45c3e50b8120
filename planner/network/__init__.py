"""The line as a network of trains: the track graph and route search, predicted
arrivals from run curves, blocking windows, overlaps, priority and deadlock.

Takes a ``Line`` (timetable included); gives routes, windows and conflict
reports (their datasets are written by :mod:`planner.datasets`). Pure: no
pandas, pyarrow or file access.
"""
