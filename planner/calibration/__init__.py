"""Calibration: measured data vs the model, on top of :mod:`planner.simulation`.

``discrepancy`` (the workflow: locate the disagreement, search the effect catalogue, the
verdict and the calibrated spec), ``compensate`` (feed-forward re-planned on the calibrated
model, open-loop tracking before/after), ``report`` (markdown, JSON and figures), ``trials``
(recordings with a hidden effect drawn from the catalogue, for testing the workflow).
"""
