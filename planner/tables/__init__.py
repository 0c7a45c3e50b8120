"""Running-time tables and what the vehicle does with them: the target-speed ratio
grid, evaluation points, tables (a)–(d), the on-board ratio choice (nearest,
interpolate, adaptive), the closed loop that proves the tables, and the
time-keeping controller.

Takes a ``Line`` and settings; gives dataclasses and arrays (their datasets are
written by :mod:`planner.datasets`). Pure: no pandas, pyarrow or file access.
"""
