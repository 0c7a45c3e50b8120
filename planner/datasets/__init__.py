"""The published datasets of the algorithm steps: each step's results as Arrow
tables with declared schemas, their writers and readers (running-time tables,
stops, closed loop, conflicts). The catalogue analysts read, which also
lists the report's datasets, is :mod:`planner.report.catalog`.

Takes the dataclasses of tables/, stopping/ and network/; gives Parquet
datasets through :mod:`planner.io.parquet` (and reads them back).
"""
