"""Machinery with no railway knowledge: atomic file writes, the Parquet dataset
writer/reader, and the one parallel map (``map_tasks``) with its backends.

Takes bytes, Arrow tables and plain callables; gives files and results. Every
other sub-package may import from here; nothing here imports them.
"""
