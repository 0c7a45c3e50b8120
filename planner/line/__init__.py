"""The line database and nothing else: its schema (the public column contract), the
loader and validator that turn a folder of Parquet files into a frozen, SI
:class:`~planner.line.model.Line`, the units used at the edges, and importers
from other formats (CSV, railML, RailJSON).

Takes a folder path; gives a ``Line`` or one-line errors naming file, row and column.
"""
