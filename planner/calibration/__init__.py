"""Calibration: measured data vs the model, on top of :mod:`planner.simulation`.

``discrepancy`` (the workflow: locate the disagreement, search the effect catalogue, the
calibrated spec), ``verdict`` (explained / named / ambiguous / unexplained), ``signature``
(the shape of a residual no effect explains), ``noise`` (the noise floor from the data; is the
log upsampled?), ``where`` (channels, windows and operating conditions of a residual),
``excite`` (a test sequence that tells candidate effects apart, optimised over a family of
feasible periodic Ruckig sequences), ``compensate``
(feed-forward re-planned on the calibrated model, open-loop tracking before/after),
``report`` (markdown, JSON and figures), ``trials`` (recordings with a hidden effect drawn
from the catalogue, for testing the workflow).
"""
