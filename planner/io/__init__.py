"""Machinery with no railway knowledge: atomic file writes, the Parquet dataset
writer/reader, the one parallel map (``map_tasks``) with its backends, the
loader of the kernels' machine code built at install (``compiled``), and the
freed memory given back to the system between steps (``memory``).

Takes bytes, Arrow tables and plain callables; gives files and results. Every
other sub-package may import from here; nothing here imports them.
"""
