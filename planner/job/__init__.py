"""Running the nightly job: the job file (``config``), the pipeline of steps with
progress and kill-safety (``pipeline``), the verified result cache (``cache``)
and publishing a run atomically (``publish``).

Takes a job file; gives a published run folder.
"""
