"""The day as it will run: delays carried forward over the blocking-time model, and Monte Carlo punctuality.

Takes the conflict check's trains, windows and planned times (:mod:`planner.network`); gives the day's
event–activity network (:mod:`.network`), the predicted day (:mod:`.predicted`), delay propagation over
many days at once (:mod:`.propagate`), primary delays (:mod:`.primary`) and the statistics of simulated
days (:mod:`.montecarlo`). Pure: no pandas, pyarrow or file access (the datasets and the page are built in
:mod:`planner.datasets.delays` and :mod:`planner.pages.robustness`).
"""
