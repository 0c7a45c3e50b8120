"""Running the nightly job: the job file (``config``), the pipeline of steps with
progress and kill-safety (``pipeline``), the verified result cache (``cache``),
publishing a run atomically (``publish``) and the run's pages built from the
report (``views``: train graph, changes since the last run, overview).

Takes a job file; gives a published run folder.
"""
