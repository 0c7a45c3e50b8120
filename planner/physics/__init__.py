"""The train's physics, once: traction and resistance (``dynamics``), the on-board
speed profile and braking curves (``speed_profile``), the track a run sees
(``track``) and the one distance-domain integrator with its controller hook
(``run_curve``); ``running_time`` is the single-run API over it.

Takes a ``Line`` (or a ``Track`` built from one); gives arrays and dataclasses.
Pure: no pandas, pyarrow, matplotlib or file access.
"""
