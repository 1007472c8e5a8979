"""Evaluation results: one run's summary files (:mod:`.run_summary`, written by ``multion eval``)
and the paper's tables and figures over many runs (``multion report``)."""
